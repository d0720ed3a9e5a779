//! The data list (both manuals' table 4), one row per entry, as rows of the shared parameter table.

use motionlink_link::table::{Access, Entry, Table};

use super::{DataEntry, FlagSet, Kind};

/// Makes one [`Entry`] per row: index, command-line name, manual name, kind, access (`ReadOnly`: RG only;
/// `ReadWrite`: remote data, written with RT).
macro_rules! data_list {
    ($( $index:literal $name:literal $title:literal $kind:ident $(($arg:expr))?, $access:ident; )*) => {
        /// Every entry of the data list, in index order (both manuals' table 4, "Data list").
        pub const DATA_LIST: &[DataEntry] = &[
            $( Entry {
                id: $index,
                name: $name,
                title: $title,
                unit: Kind::$kind $(($arg))?.unit(),
                access: data_list!(@access $access),
                kind: Kind::$kind $(($arg))?,
            }, )*
        ];
    };
    (@access ReadOnly) => { Access::Read };
    (@access ReadWrite) => { Access::ReadWrite };
}

data_list! {
    0x0001 "firmware_info" "Firmware info Name Version CS" Text(31), ReadOnly;
    0x0002 "configuration_info" "Configuration info Name Version CS" Text(36), ReadOnly;
    0x0011 "actual_position_a1" "Actual_Position Actuator 1" PositionCounts, ReadOnly;
    0x0012 "actual_position_a2" "Actual_Position Actuator 2" PositionCounts, ReadOnly;
    0x0013 "actual_position_a3" "Actual_Position Actuator 3" PositionCounts, ReadOnly;
    0x0014 "actual_position_a4" "Actual_Position Actuator 4" PositionCounts, ReadOnly;
    0x0015 "actual_position_a5" "Actual_Position Actuator 5" PositionCounts, ReadOnly;
    0x0016 "actual_position_a6" "Actual_Position Actuator 6" PositionCounts, ReadOnly;
    0x0020 "binary_inputs" "Actual_State_Binary Inputs 1..4" Flags(FlagSet::BinaryInputs), ReadOnly;
    0x0031 "analogue_input_1" "Actual_State_Analogue_Input_1" AnalogueCentiVolts, ReadOnly;
    0x0032 "analogue_input_2" "Actual_State_Analogue_Input_2" AnalogueCentiVolts, ReadOnly;
    0x0033 "analogue_input_3" "Actual_State_Analogue_Input_3" AnalogueCentiVolts, ReadOnly;
    0x0034 "analogue_input_4" "Actual_State_Analogue_Input_4" AnalogueCentiVolts, ReadOnly;
    0x0040 "keys" "Actual_State_Keys" Flags(FlagSet::Keys), ReadOnly;
    0x0061 "relay_in_cycles_a1" "Number_cycle_off_on_off_Relay_in A1" Counter, ReadOnly;
    0x0062 "relay_in_cycles_a2" "Number_cycle_off_on_off_Relay_in A2" Counter, ReadOnly;
    0x0063 "relay_in_cycles_a3" "Number_cycle_off_on_off_Relay_in A3" Counter, ReadOnly;
    0x0064 "relay_in_cycles_a4" "Number_cycle_off_on_off_Relay_in A4" Counter, ReadOnly;
    0x0065 "relay_in_cycles_a5" "Number_cycle_off_on_off_Relay_in A5" Counter, ReadOnly;
    0x0066 "relay_in_cycles_a6" "Number_cycle_off_on_off_Relay_in A6" Counter, ReadOnly;
    0x0071 "relay_out_cycles_a1" "Number_cycle_off_on_off_Relay_out A1" Counter, ReadOnly;
    0x0072 "relay_out_cycles_a2" "Number_cycle_off_on_off_Relay_out A2" Counter, ReadOnly;
    0x0073 "relay_out_cycles_a3" "Number_cycle_off_on_off_Relay_out A3" Counter, ReadOnly;
    0x0074 "relay_out_cycles_a4" "Number_cycle_off_on_off_Relay_out A4" Counter, ReadOnly;
    0x0075 "relay_out_cycles_a5" "Number_cycle_off_on_off_Relay_out A5" Counter, ReadOnly;
    0x0076 "relay_out_cycles_a6" "Number_cycle_off_on_off_Relay_out A6" Counter, ReadOnly;
    0x0081 "actuator_errors_a1" "Number_Actuator error A1" ActuatorErrorCounter, ReadOnly;
    0x0082 "actuator_errors_a2" "Number_Actuator error A2" ActuatorErrorCounter, ReadOnly;
    0x0083 "actuator_errors_a3" "Number_Actuator error A3" ActuatorErrorCounter, ReadOnly;
    0x0084 "actuator_errors_a4" "Number_Actuator error A4" ActuatorErrorCounter, ReadOnly;
    0x0085 "actuator_errors_a5" "Number_Actuator error A5" ActuatorErrorCounter, ReadOnly;
    0x0086 "actuator_errors_a6" "Number_Actuator error A6" ActuatorErrorCounter, ReadOnly;
    0x008F "total_over_current_count" "Number_Total_Over_Current" Counter, ReadOnly;
    0x0091 "cumulated_stroke_a1" "Cumulated_Stroke A1" StrokeCounts, ReadOnly;
    0x0092 "cumulated_stroke_a2" "Cumulated_Stroke A2" StrokeCounts, ReadOnly;
    0x0093 "cumulated_stroke_a3" "Cumulated_Stroke A3" StrokeCounts, ReadOnly;
    0x0094 "cumulated_stroke_a4" "Cumulated_Stroke A4" StrokeCounts, ReadOnly;
    0x0095 "cumulated_stroke_a5" "Cumulated_Stroke A5" StrokeCounts, ReadOnly;
    0x0096 "cumulated_stroke_a6" "Cumulated_Stroke A6" StrokeCounts, ReadOnly;
    0x00A1 "current_a1" "Current A1" CurrentDeciAmps, ReadOnly;
    0x00A2 "current_a2" "Current A2" CurrentDeciAmps, ReadOnly;
    0x00A3 "current_a3" "Current A3" CurrentDeciAmps, ReadOnly;
    0x00A4 "current_a4" "Current A4" CurrentDeciAmps, ReadOnly;
    0x00A5 "current_a5" "Current A5" CurrentDeciAmps, ReadOnly;
    0x00A6 "current_a6" "Current A6" CurrentDeciAmps, ReadOnly;
    0x00B1 "max_current_a1" "Max_Current A1" CurrentDeciAmps, ReadOnly;
    0x00B2 "max_current_a2" "Max_Current A2" CurrentDeciAmps, ReadOnly;
    0x00B3 "max_current_a3" "Max_Current A3" CurrentDeciAmps, ReadOnly;
    0x00B4 "max_current_a4" "Max_Current A4" CurrentDeciAmps, ReadOnly;
    0x00B5 "max_current_a5" "Max_Current A5" CurrentDeciAmps, ReadOnly;
    0x00B6 "max_current_a6" "Max_Current A6" CurrentDeciAmps, ReadOnly;
    0x00BF "max_total_current" "Max_Total_Current" CurrentDeciAmps, ReadOnly;
    0x00C0 "max_temp_rectifier_fet" "Max_Temp_Rectifier_FET" TemperatureAdc, ReadOnly;
    0x00C1 "over_temp_count_rectifier_fet" "Number_Over_Temp_Rectifier_FET" Counter, ReadOnly;
    0x00D1 "error_code_1" "Error_Code 1 (last recent)" ErrorCode, ReadOnly;
    0x00D2 "error_code_2" "Error_Code 2 (History 1)" ErrorCode, ReadOnly;
    0x00D3 "error_code_3" "Error_Code 3 (History 2)" ErrorCode, ReadOnly;
    0x00D4 "error_code_4" "Error_Code 4 (History 3)" ErrorCode, ReadOnly;
    0x00D5 "error_code_5" "Error_Code 5 (History 4)" ErrorCode, ReadOnly;
    0x00E1 "actuator_status2_a1" "Actuator status 2 A1" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E2 "actuator_status2_a2" "Actuator status 2 A2" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E3 "actuator_status2_a3" "Actuator status 2 A3" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E4 "actuator_status2_a4" "Actuator status 2 A4" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E5 "actuator_status2_a5" "Actuator status 2 A5" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E6 "actuator_status2_a6" "Actuator status 2 A6" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00F1 "speed_a1" "Speed A1" SpeedPercent, ReadOnly;
    0x00F2 "speed_a2" "Speed A2" SpeedPercent, ReadOnly;
    0x00F3 "speed_a3" "Speed A3" SpeedPercent, ReadOnly;
    0x00F4 "speed_a4" "Speed A4" SpeedPercent, ReadOnly;
    0x00F5 "speed_a5" "Speed A5" SpeedPercent, ReadOnly;
    0x00F6 "speed_a6" "Speed A6" SpeedPercent, ReadOnly;
    0x0100 "battery_mains" "Battery Mains" Flags(FlagSet::BatteryMains), ReadOnly;
    0x0110 "binary_outputs" "Binary Output Status" Flags(FlagSet::BinaryOutputs), ReadOnly;
    0x0120 "led_hand_switch" "LED HS" Flags(FlagSet::LedHandSwitch), ReadOnly;
    0x0130 "led_locking_box" "LED LB" Flags(FlagSet::LedLockingBox), ReadOnly;
    0x0140 "buzzer" "Buzzer" Flags(FlagSet::Buzzer), ReadOnly;
    0x0150 "sensor_supply" "Sensor Supply" Flags(FlagSet::SensorSupply), ReadOnly;
    0x0162 "lock_status" "Lock Status" Flags(FlagSet::LockStatus), ReadOnly;
    0x0164 "battery_voltage" "Battery voltage" BatteryDeciVolts, ReadOnly;
    0x0165 "locking_box_detected" "Locking Box detected" Number, ReadOnly;
    0x0166 "user" "User" Number, ReadOnly;
    0x0171 "actuator_status1_a1" "Actuator Status 1 A1" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0172 "actuator_status1_a2" "Actuator Status 1 A2" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0173 "actuator_status1_a3" "Actuator Status 1 A3" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0174 "actuator_status1_a4" "Actuator Status 1 A4" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0175 "actuator_status1_a5" "Actuator Status 1 A5" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0176 "actuator_status1_a6" "Actuator Status 1 A6" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x1011 "conversion_factor_a1" "Conversion factor A1" ConversionFactor, ReadOnly;
    0x1012 "conversion_factor_a2" "Conversion factor A2" ConversionFactor, ReadOnly;
    0x1013 "conversion_factor_a3" "Conversion factor A3" ConversionFactor, ReadOnly;
    0x1014 "conversion_factor_a4" "Conversion factor A4" ConversionFactor, ReadOnly;
    0x1015 "conversion_factor_a5" "Conversion factor A5" ConversionFactor, ReadOnly;
    0x1016 "conversion_factor_a6" "Conversion factor A6" ConversionFactor, ReadOnly;
    0x2001 "user_positions_a1" "UserPositionData A1" UserPositions, ReadOnly;
    0x2002 "user_positions_a2" "UserPositionData A2" UserPositions, ReadOnly;
    0x2003 "user_positions_a3" "UserPositionData A3" UserPositions, ReadOnly;
    0x2004 "user_positions_a4" "UserPositionData A4" UserPositions, ReadOnly;
    0x2005 "user_positions_a5" "UserPositionData A5" UserPositions, ReadOnly;
    0x2006 "user_positions_a6" "UserPositionData A6" UserPositions, ReadOnly;
    0x3001 "cyclic_obj_1" "CyclicObj 1" CyclicObject, ReadWrite;
    0x3002 "cyclic_obj_2" "CyclicObj 2" CyclicObject, ReadWrite;
    0x3003 "cyclic_obj_3" "CyclicObj 3" CyclicObject, ReadWrite;
    0x3004 "cyclic_obj_4" "CyclicObj 4" CyclicObject, ReadWrite;
    0x3005 "cyclic_obj_5" "CyclicObj 5" CyclicObject, ReadWrite;
    0x3011 "remote_speed_f1" "Remote Speed F1" RemoteSpeed, ReadWrite;
    0x3012 "remote_speed_f2" "Remote Speed F2" RemoteSpeed, ReadWrite;
    0x3013 "remote_speed_f3" "Remote Speed F3" RemoteSpeed, ReadWrite;
    0x3014 "remote_speed_f4" "Remote Speed F4" RemoteSpeed, ReadWrite;
    0x3015 "remote_speed_f5" "Remote Speed F5" RemoteSpeed, ReadWrite;
    0x3016 "remote_speed_f6" "Remote Speed F6" RemoteSpeed, ReadWrite;
    0x3017 "remote_speed_f7" "Remote Speed F7" RemoteSpeed, ReadWrite;
    0x3018 "remote_speed_f8" "Remote Speed F8" RemoteSpeed, ReadWrite;
    0x3019 "remote_speed_f9" "Remote Speed F9" RemoteSpeed, ReadWrite;
    0x301A "remote_speed_f10" "Remote Speed F10" RemoteSpeed, ReadWrite;
    0x3021 "remote_position_a1" "Remote Position A1" RemotePosition, ReadWrite;
    0x3022 "remote_position_a2" "Remote Position A2" RemotePosition, ReadWrite;
    0x3023 "remote_position_a3" "Remote Position A3" RemotePosition, ReadWrite;
    0x3024 "remote_position_a4" "Remote Position A4" RemotePosition, ReadWrite;
    0x3025 "remote_position_a5" "Remote Position A5" RemotePosition, ReadWrite;
    0x3026 "remote_position_a6" "Remote Position A6" RemotePosition, ReadWrite;
}

/// The data list as the shared table: found by name or by number (`0x0011`, `17`) the same way as in every
/// family. Groups (0x0010 ...) are not entries: see [`super::item`] and [`super::lookup`].
pub static TABLE: Table<Kind> = Table::new("data list", DATA_LIST);
