//! Tests of the model: the tables and the decisions taken where the manuals differ.

use super::*;

#[test]
fn data_list_is_sorted_unique_and_names_are_unique() {
    for w in DATA_LIST.windows(2) {
        assert!(w[0].index() < w[1].index(), "{} then {}", w[0].index(), w[1].index());
    }
    let mut names: Vec<_> = DATA_LIST.iter().map(|e| e.name).chain(GROUPS.iter().map(|g| g.name)).collect();
    names.sort_unstable();
    let before = names.len();
    names.dedup();
    assert_eq!(before, names.len(), "duplicate names");
}

#[test]
fn where_the_editions_differ_the_decisions_hold() {
    // Battery Mains bit 2 set: the charge controller is on (the Schaeffler edition's reading).
    let b = FlagSet::BatteryMains.bit("charge_controller").unwrap();
    assert_eq!((b.bit, b.set, b.clear), (2, "charge controller on", "charge controller off"));
    // Error bits 29, 30 and 32 have causes of their own (the Ewellix edition's).
    let cause = |n: u8| ErrorBit::ALL.iter().find(|b| b.number() == n).unwrap().cause();
    assert!(cause(29).contains("calibration"));
    assert!(cause(30).contains("hardware settings"));
    assert!(cause(32).contains("operating system"));
    assert_eq!(Function::from_id(21).map(Function::description), Some("operating unit LED 2"));
}

#[test]
fn only_remote_entries_are_writable() {
    for e in DATA_LIST {
        assert_eq!(e.access == Access::ReadWrite, e.index().is_remote(), "{}", e.name);
    }
}

#[test]
fn groups_cover_their_members() {
    let g = |i| item(DataIndex(i)).unwrap();
    assert_eq!(g(0x0010).size(), 24);
    assert_eq!(g(0x0080).size(), 7 * 4, "0x0080 includes Number_Total_Over_Current 0x008F");
    assert_eq!(g(0x00B0).size(), 7 * 2, "0x00B0 includes Max_Total_Current 0x00BF");
    assert_eq!(g(0x2000).size(), 6 * 104);
    assert_eq!(g(0x0000).size(), 31 + 36);
    for group in GROUPS {
        assert!(group.members().count() > 0, "{}", group.name);
        assert!(entry(group.index).is_none(), "a group index is not also an entry");
    }
}

#[test]
fn lookup_by_name_or_index() {
    assert_eq!(lookup("0x0171").unwrap().name(), "actuator_status1_a1");
    assert_eq!(lookup("0171").unwrap().name(), "actuator_status1_a1");
    assert_eq!(lookup("REMOTE_SPEED_F1").unwrap().index(), DataIndex(0x3011));
    assert_eq!(lookup("actual_positions").unwrap().index(), DataIndex(0x0010));
    assert!(lookup("0x0017").is_none());
    assert!(lookup("nonsense").is_none());
}

#[test]
fn error_bits_follow_the_decision_bit_n_is_mask_1_shl_n_minus_1() {
    assert_eq!(error_bit(1).unwrap().mask(), 0x0000_0001);
    assert_eq!(error_bit(22).unwrap().mask(), 0x0020_0000);
    assert_eq!(error_bit(32).unwrap().mask(), 0x8000_0000);
    assert!(error_bit(9).is_none() && error_bit(23).is_none());
    assert_eq!(ErrorBit::ALL.len(), 30);
    let code = ErrorCode::from_bit(22);
    assert!(code.has(22) && !code.has(21));
    assert_eq!(code.bits().map(|b| b.name()).collect::<Vec<_>>(), ["remote_timeout"]);
    assert!(code.to_string().contains("remote communication time out"));
    assert_eq!(ErrorCode(1 << 8).unknown_bits(), 1 << 8, "bit 9 is undefined");
}

#[test]
fn functions_map_to_wire_ids() {
    assert_eq!(Function::parse("F1"), Some(Function::Motion(MotionFunction::new(1).unwrap())));
    assert_eq!(Function::parse("f11"), Some(Function::Buzzer));
    assert_eq!(Function::parse("20").map(Function::id), Some(19));
    assert_eq!(Function::parse("F12"), None, "F12..F16 and F19 are not in the function list");
    assert_eq!(Function::parse("F19"), None);
    for id in 0..=255u8 {
        if let Some(f) = Function::from_id(id) {
            assert_eq!(f.id(), id);
        }
    }
}

#[test]
fn structures_round_trip() {
    let mut data = UserPositionData::default();
    data.users[2].memory_counts[1] = -5;
    data.virtual_limit_out_counts = 865;
    let mut bytes = Vec::new();
    data.write_to(&mut bytes);
    assert_eq!(bytes.len(), UserPositionData::SIZE);
    assert_eq!(UserPositionData::from_bytes(&bytes), Some(data));
    assert_eq!(&bytes[100..104], &865i32.to_le_bytes());

    let obj = CyclicObject::new(&[DataIndex(0x3021)], &[DataIndex(0x0011), DataIndex(0x0171)]).unwrap();
    assert_eq!(CyclicObject::from_bytes(&obj.to_bytes()), Some(obj));
    assert_eq!(obj.write_size(), Some(4));
    assert_eq!(obj.read_size(), Some(5));
    assert_eq!(&obj.to_bytes()[..4], &[0x21, 0x30, 0xFF, 0xFF]);

    let c = ActuatorErrorCount { errors: 0x0102, peak_current: 3, short_circuit: 4 };
    assert_eq!(c.to_u32(), 0x0403_0102);
    assert_eq!(ActuatorErrorCount::from_u32(c.to_u32()), c);
}

#[test]
fn every_direction_name_parses_and_a_misspelt_name_suggests_the_nearest_entry() {
    for name in MotionDirection::NAMES {
        assert!(MotionDirection::parse(name).is_some(), "{name}");
    }
    assert_eq!(suggest("remote_sped_f1"), vec!["remote_speed_f1"]);
    assert_eq!(suggest("actual_positons"), vec!["actual_positions"], "groups are suggested too");
    assert!(suggest("temperature").is_empty());
    let e = find("remote_sped_f1").unwrap_err().to_string();
    assert_eq!(e, "\"remote_sped_f1\" is not in the data list: did you mean remote_speed_f1?");
    assert!(find("xyz").unwrap_err().to_string().contains("such as actual_position_a1"));
    assert!(find("0x0011").is_ok() && find("Remote_Speed_F1").is_ok());
}
