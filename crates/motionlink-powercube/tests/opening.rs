//! Opening a session by the port's name (`Client::open`, `AsyncClient::open`), as a user's program does.

use std::sync::{Arc, Mutex};

use motionlink_link::emulator::{serve_tcp, Server};
use motionlink_link::error::{Classify, ErrorClass};
use motionlink_link::RealClock;
use motionlink_powercube::client::{Client, Config};
use motionlink_powercube::model::Address;
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::Emulator;

/// Module 3 on an RS232 chain served over TCP.
fn served() -> (Arc<Mutex<Emulator>>, Server) {
    let bus = Arc::new(Mutex::new(Emulator::new(&SimConfig::with_addresses(&[3]).unwrap())));
    let server = serve_tcp("127.0.0.1:0", Arc::clone(&bus), RealClock::shared()).unwrap();
    (bus, server)
}

#[test]
fn a_chain_opened_by_the_port_s_name_runs_over_tcp_and_sim_is_refused_naming_what_to_do() {
    let (_bus, server) = served();
    let clock = RealClock::shared();
    let client = Client::open(&server.address().parse().unwrap(), clock.clone(), Config::rs232()).unwrap();
    assert!(!client.is_can());
    client.module(Address::new(3).unwrap()).position().unwrap();
    client.close().unwrap();
    let err = Client::open(&"sim".parse().unwrap(), clock, Config::rs232()).unwrap_err();
    assert!(err.to_string().contains("give its link to `with_link`"), "{err}");
    assert_eq!(err.class(), ErrorClass::Usage);
}

#[cfg(feature = "tokio")]
#[test]
fn an_async_chain_opened_by_the_port_s_name_runs_over_tcp() {
    let (_bus, server) = served();
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    runtime.block_on(async {
        let url = server.address().parse().unwrap();
        let client = motionlink_powercube::AsyncClient::open(&url, RealClock::shared(), Config::rs232()).await.unwrap();
        client.module(Address::new(3).unwrap()).position().await.unwrap();
        client.close().await.unwrap();
    });
}
