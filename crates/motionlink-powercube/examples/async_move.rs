//! With tokio: positions read concurrently while a checked move runs against the in-process emulator
//! (two modules on a CAN bus paced at 1 Mbit/s, real time), then the move cancelled by dropping its
//! future: the session halts the module, and the example shows it halted.
//!
//! `cargo run -p motionlink-powercube --example powercube_async_move --features tokio`

use motionlink_powercube::PortLink;
use std::time::Duration;

use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::RealClock;
use motionlink_powercube::client::{AsyncClient, Config, MoveSpec};
use motionlink_powercube::model::{Acceleration, Address, CubeState, Position, StateFlag, Velocity};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::{Emulator, Error};

/// What the example saw.
#[derive(Debug)]
pub struct Seen {
    /// Module 1's positions read while its move ran (module 2 was read in the same rounds).
    pub during: Vec<Position>,
    /// Module 1's state after its move's future was dropped.
    pub after: CubeState,
    /// Where module 1 stood after the halt, read twice some time apart.
    pub stopped_at: (Position, Position),
    /// The emulator's own account of module 1 (its events).
    pub events: Vec<String>,
}

/// Runs the example; what it saw, for the test that runs it too (`tests/async_example.rs`).
pub async fn run() -> Result<Seen, Error> {
    let clock = RealClock::shared();
    let config = SimConfig::with_addresses(&[1, 2]).map_err(|e| Error::NotSupported(e.to_string()))?;
    let sim = Emulator::new_can(&config);
    let bus = CanBus::with_emulator(sim, clock.clone(), CanBusConfig::paced(1_000_000));
    let client = AsyncClient::with_link(PortLink::Can(Box::new(bus.connect())), clock, Config::can()).await?;
    let (one, two) = (Address::new(1)?, Address::new(2)?);
    let joint = client.module(one);
    println!("module 1 is {}", joint.kind().await?.name()); // from now on its positions read in rad
    let spec = MoveSpec {
        vel: Some(Velocity::rad_per_s(0.5)),
        acc: Some(Acceleration::rad_per_s2(2.0)),
        ..MoveSpec::to(Position::rad(2.0))
    };
    // Boxed, so that dropping it below really drops the future (a `tokio::pin!` would keep it alive to the
    // end of the scope).
    let mut moving = Box::pin(joint.move_to(&spec));
    let mut during = Vec::new();
    // The move runs in the session whether or not its future is polled; meanwhile, every 50 ms, positions.
    loop {
        if let Ok(done) = tokio::time::timeout(Duration::from_millis(50), moving.as_mut()).await {
            println!("the move ended before it was cancelled: {done:?}");
            return Err(Error::NotSupported("the move ended too soon".into()));
        }
        let both = client.positions(&[one, two]).await;
        let p = both[0].as_ref().map_err(|e| Error::NotSupported(e.to_string()))?;
        println!(
            "module 1 at {p}, module 2 at {}",
            both[1].as_ref().map_or_else(ToString::to_string, ToString::to_string)
        );
        during.push(*p);
        if p.value() > 0.4 {
            break;
        }
    }
    // Cancelling is dropping: the session halts what the move started.
    drop(moving);
    let mut after = joint.state().await?;
    for _ in 0..100 {
        if after.contains(StateFlag::Halted) && !after.contains(StateFlag::Motion) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
        after = joint.state().await?;
    }
    let first = joint.position().await?;
    tokio::time::sleep(Duration::from_millis(100)).await;
    let second = joint.position().await?;
    println!("after the drop: module 1 stands at {second} ({after})");
    let events: Vec<String> = bus
        .with_device(|d| d.take_events())
        .unwrap_or_default()
        .into_iter()
        .filter(|e| e.starts_with("module 1"))
        .collect();
    client.close().await?;
    Ok(Seen { during, after, stopped_at: (first, second), events })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A tokio runtime made by hand (what `#[tokio::main]` would write).
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    runtime.block_on(async {
        let seen = run().await?;
        println!("{} positions read while moving; the emulator says: {:?}", seen.during.len(), seen.events);
        Ok(())
    })
}
