use super::*;

const FILE: &str = r#"
[gateway]
name = "wing-a"
broker = "mqtt://127.0.0.1:1883"

[device.lift]
family = "scu"
port = "sim"
functions = "tlt"

[device.arm]
family = "powercube"
port = "sim"
module = 3
"#;

fn parsed(text: &str, options: &Options, env: Option<&str>) -> Result<GatewayConfig, GatewayError> {
    let env = env.map(str::to_string);
    parse(text, "gw.toml", options, move |_| env.clone(), |_| Ok("s3cret\n".to_string()))
}

fn message(r: Result<GatewayConfig, GatewayError>) -> String {
    match r {
        Err(GatewayError::Usage(m)) => m,
        other => panic!("a usage error, not {other:?}"),
    }
}

#[test]
fn the_file_gives_the_gateway_and_its_devices() {
    let c = parsed(FILE, &Options::default(), None).unwrap();
    assert_eq!((c.name.as_str(), c.sample_hz, c.broker.port), ("wing-a", 10, 1883));
    let names: Vec<&str> = c.devices.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, ["arm", "lift"]);
    assert_eq!(c.devices[0].options["module"], toml::Value::Integer(3));
    assert!(c.credentials.is_none());
    let o = Options { name: Some("cell-2".into()), broker: Some("mqtt://localhost".into()), ..Options::default() };
    let c = parsed(FILE, &o, None).unwrap();
    assert_eq!((c.name.as_str(), c.broker.to_string()), ("cell-2", "mqtt://localhost:1883".to_string()));
}

#[test]
fn broker_urls_are_mqtt_or_mqtts() {
    let u = BrokerUrl::parse("mqtts://broker.example:8884").unwrap();
    assert_eq!((u.host.as_str(), u.port, u.tls, u.is_loopback()), ("broker.example", 8884, true, false));
    assert_eq!(BrokerUrl::parse("mqtts://b").unwrap().port, 8883);
    let v6 = BrokerUrl::parse("mqtt://[::1]:1884").unwrap();
    assert!(v6.is_loopback() && v6.to_string() == "mqtt://[::1]:1884");
    assert!(BrokerUrl::parse("mqtt://127.3.2.1").unwrap().is_loopback());
    for bad in ["tcp://h:1", "mqtt://", "mqtt://h:0", "mqtt://h:99999", "h:1883"] {
        assert!(BrokerUrl::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn a_bracketed_address_takes_nothing_or_a_port_after_it() {
    // An IPv6 address without brackets is refused, not read as host and port.
    for bare in ["mqtt://::1", "mqtt://2001:db8::1:1883"] {
        let e = BrokerUrl::parse(bare).unwrap_err();
        assert!(e.contains("goes in brackets"), "{bare}: {e}");
    }
    // The valid forms: the default port, a port given; host names and IPv4 as before.
    let v6 = BrokerUrl::parse("mqtt://[::1]").unwrap();
    assert_eq!((v6.host.as_str(), v6.port, v6.tls), ("::1", 1883, false));
    assert_eq!(BrokerUrl::parse("mqtts://[2001:db8::1]").unwrap().port, 8883);
    let v6 = BrokerUrl::parse("mqtt://[::1]:1884").unwrap();
    assert_eq!((v6.host.as_str(), v6.port), ("::1", 1884));
    assert_eq!(BrokerUrl::parse("mqtt://[::1]:1884/").unwrap().port, 1884);
    assert_eq!(BrokerUrl::parse("mqtt://broker.example:1885").unwrap().port, 1885);
    assert_eq!(BrokerUrl::parse("mqtt://10.1.2.3").unwrap().port, 1883);
    // What follows `]` is not dropped for the default port: the error names the broker and what was there.
    let m = BrokerUrl::parse("mqtt://[2001:db8::1]junk").unwrap_err();
    assert_eq!(
        m,
        "broker \"mqtt://[2001:db8::1]junk\": unexpected \"junk\" after [2001:db8::1]: give [ADDRESS] or \
         [ADDRESS]:PORT"
    );
    let m = BrokerUrl::parse("mqtt://[::1]8883").unwrap_err();
    assert!(m.starts_with("broker \"mqtt://[::1]8883\": unexpected \"8883\" after [::1]"), "{m}");
    // A bad port after `:` is still the port's error.
    for bad in ["mqtt://[::1]:", "mqtt://[::1]:0", "mqtt://[::1]:x", "mqtt://[::1]:1884:1"] {
        let m = BrokerUrl::parse(bad).unwrap_err();
        assert!(m.contains("the port must be a number"), "{bad}: {m}");
    }
    // Through the file and --broker: a usage error naming the value.
    let o = Options { broker: Some("mqtt://[::1]8883".into()), ..Options::default() };
    let m = message(parsed(FILE, &o, None));
    assert!(m.contains("mqtt://[::1]8883") && m.contains("\"8883\""), "{m}");
    let m =
        message(parsed(&FILE.replace("mqtt://127.0.0.1:1883", "mqtt://[2001:db8::1]junk"), &Options::default(), None));
    assert!(m.contains("mqtt://[2001:db8::1]junk") && m.contains("\"junk\""), "{m}");
}

#[test]
fn a_remote_broker_without_tls_is_refused_unless_asked() {
    let o = Options { broker: Some("mqtt://10.1.2.3:1883".into()), ..Options::default() };
    let m = message(parsed(FILE, &o, None));
    assert!(m.contains("mqtt://10.1.2.3:1883") && m.contains("--insecure-broker"), "{m}");
    let o = Options { insecure_broker: true, ..o };
    assert!(parsed(FILE, &o, None).is_ok());
    let o = Options { broker: Some("mqtts://10.1.2.3".into()), ..Options::default() };
    assert!(parsed(FILE, &o, None).is_ok());
}

#[test]
fn the_password_comes_from_its_file_or_the_environment_never_the_config() {
    let with = |gateway: &str| FILE.replace("name = \"wing-a\"", gateway);
    let c = parsed(&with("name = \"g\"\nusername = \"gw\"\npassword_file = \"/p\""), &Options::default(), None);
    assert_eq!(c.unwrap().credentials, Some(("gw".into(), "s3cret".into())));
    let c = parsed(&with("name = \"g\"\nusername = \"gw\""), &Options::default(), Some("from-env")).unwrap();
    assert_eq!(c.credentials, Some(("gw".into(), "from-env".into())));
    let m = message(parsed(&with("name = \"g\"\nusername = \"gw\"\npassword = \"x\""), &Options::default(), None));
    assert!(m.contains("password_file") && m.contains(PASSWORD_ENV), "{m}");
    let m = message(parsed(&with("name = \"g\""), &Options::default(), Some("p")));
    assert!(m.contains("username"), "{m}");
}

#[test]
fn mistakes_are_named() {
    let cases = [
        (FILE.replace("sample_hz", "x").replace("name = \"wing-a\"", "name = \"wing-a\"\nsample_hz = 0"), "sample_hz"),
        (FILE.replace("name = \"wing-a\"", "name = \"a/b\""), "\"a/b\""),
        (FILE.replace("name = \"wing-a\"", "name = \"w\"\nbrokr = \"x\""), "brokr"),
        (FILE.replace("family = \"scu\"", "family = \"plc\""), "[device.lift]"),
        (FILE.replace("port = \"sim\"\nfunctions", "functions"), "`port` is missing"),
        (FILE.replace("[device.lift]", "[device.\"li+ft\"]"), "li+ft"),
        (FILE.replace("mqtt://127.0.0.1:1883", "mqtt://127.0.0.1:1883\"\nca_file = \"/ca.pem"), "ca_file"),
    ];
    for (text, said) in cases {
        let m = message(parsed(&text, &Options::default(), None));
        assert!(m.contains(said) && m.starts_with("gw.toml: "), "{said}: {m}");
    }
    let m = message(parsed("[gateway]\nname = \"g\"\nbroker = \"mqtt://localhost\"\n", &Options::default(), None));
    assert!(m.contains("no [device.NAME]"), "{m}");
    // `--sim-variant`'s key by its option's name, as the command line's devices.toml takes it.
    let c = parsed(
        &FILE.replace("functions = \"tlt\"", "functions = \"tlt\"\nsim_variant = \"no-groups\""),
        &Options::default(),
        None,
    )
    .unwrap();
    let lift = c.devices.iter().find(|d| d.name == "lift").unwrap();
    assert!(lift.options.contains_key("sim_variants"), "{:?}", lift.options);
    crate::device::Spec::of(lift).unwrap();
    // One key twice, spelt two ways.
    let m = message(parsed(
        &FILE.replace("port = \"sim\"", "port = \"sim\"\npoll_ms = 50\npoll-ms = 60"),
        &Options::default(),
        None,
    ));
    assert!(m.contains("given twice"), "{m}");
    // A bad --name is the command line's, not the file's.
    let o = Options { name: Some("bad/name".into()), ..Options::default() };
    let m = message(parsed(FILE, &o, None));
    assert!(m.starts_with("--name: the gateway's name \"bad/name\""), "{m}");
}

/// The gateway file of docs/fleet.md is one the gateway takes: every key, every device's options.
#[test]
fn the_documented_gateway_file_is_read_by_the_gateway() {
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/fleet.md")).unwrap();
    let block = page
        .split("```toml not-run\n")
        .skip(1)
        .map(|rest| rest.split("```").next().unwrap())
        .find(|b| b.contains("[gateway]"))
        .expect("a gateway file in docs/fleet.md");
    let c = parsed(block, &Options::default(), None).unwrap();
    assert_eq!((c.name.as_str(), c.broker.tls, c.sample_hz), ("wing-a", true, 10));
    assert_eq!(c.credentials, Some(("gw-wing-a".to_string(), "s3cret".to_string())));
    assert_eq!(c.devices.len(), 3);
    for d in &c.devices {
        crate::device::Spec::of(d).unwrap_or_else(|e| panic!("{}: {e}", d.name));
    }
}

#[test]
fn two_tables_on_one_port_are_refused_naming_both_and_the_port() {
    let two = |a: &str, b: &str| {
        format!(
            "[gateway]\nname = \"g\"\nbroker = \"mqtt://127.0.0.1\"\n\n\
             [device.d]\nfamily = \"compax\"\nport = \"{a}\"\n\n\
             [device.e]\nfamily = \"compax\"\nport = \"{b}\"\ndrive = 2\n"
        )
    };
    let m = message(parsed(&two("tcp://127.0.0.1:4001", "tcp://127.0.0.1:4001"), &Options::default(), None));
    assert!(
        m.starts_with(
            "gw.toml: [device.d] and [device.e] both name the port \"tcp://127.0.0.1:4001\": a gateway serves one \
             device per port"
        ),
        "{m}"
    );
    assert!(m.ends_with("remove one of the tables, or give each device a port (a line) of its own"), "{m}");
    // The same port spelt otherwise is the same port.
    let m = message(parsed(&two("tcp://LOCALHOST:4001", "tcp://localhost:4001"), &Options::default(), None));
    assert!(m.contains("both name the port \"tcp://localhost:4001\" (as \"tcp://LOCALHOST:4001\")"), "{m}");
    let m = message(parsed(&two("/dev/ttyUSB7", "serial:///dev/ttyUSB7"), &Options::default(), None));
    assert!(m.contains("[device.d] and [device.e] both name the port"), "{m}");
    let m = message(parsed(&two("socketcan://can0", "socketcan://can0"), &Options::default(), None));
    assert!(m.contains("both name the port \"socketcan://can0\""), "{m}");
    // Emulators are each table's own; other ports are other ports.
    parsed(&two("sim", "sim"), &Options::default(), None).unwrap();
    parsed(&two("tcp://127.0.0.1:4001", "tcp://127.0.0.1:4002"), &Options::default(), None).unwrap();
}
