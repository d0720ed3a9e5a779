//! The async client (feature `tokio`) against the in-process emulator: a long move runs while another
//! future reads drive 1's position again and again on the same client; then the move's future is dropped
//! (the reads finished first in a `select!`), which cancels its operation: the session stops the axis
//! (`OUTPUT O0=0`, confirmed by S17). The example shows the drive stopped and switched off.
//!
//! ```text
//! cargo run -p motionlink-compax --example compax_async_move --features tokio
//! ```
//!
//! `tests/async_example.rs` runs the same code in `cargo test`.

use std::future::Future as _;
use std::task::Poll;
use std::time::Duration;

use motionlink_compax::client::{Config, MoveRequest, MoveTarget};
use motionlink_compax::model::{Position, S17Flag, SpeedPercent};
use motionlink_compax::sim::SimConfig;
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{AsyncClient, Emulator};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::RealClock;

/// What the example saw.
#[derive(Debug)]
pub struct Summary {
    /// Drive 1's positions read while its move ran.
    pub during: Vec<f64>,
    /// Where it came to rest after the move's future was dropped.
    pub stopped_at: f64,
    /// The same 200 ms later.
    pub later: f64,
    /// S16's O0 state after the stop (0: switched off).
    pub o0: u8,
    /// S17 "command active" after the stop.
    pub moving: bool,
}

/// Runs the example; returns what it saw.
pub async fn run() -> Result<Summary, Box<dyn std::error::Error>> {
    let clock = RealClock::shared();
    let sim = Emulator::new(SimConfig::bus(&[1], 0, 115_200))?;
    let host = EmulatorHost::new(sim, clock.clone(), PipeConfig::paced(115_200));
    let client =
        AsyncClient::with_link(Box::new(host.connect().0), clock, Config::new(Mode::default(), 115_200)).await?;
    let one = Address::drive(1)?;

    // 1000 units at 50 units/s: 20 s unless stopped.
    let mut request = MoveRequest::new(MoveTarget::Absolute(Position::new(1000.0)?));
    request.speed = Some(SpeedPercent::new(50.0)?);
    let readings = async {
        let mut seen = Vec::new();
        for _ in 0..8 {
            tokio::time::sleep(Duration::from_millis(40)).await;
            let p = client.read_position(one).await?;
            println!("while the move runs: drive 1 at {p}");
            seen.push(p.units());
        }
        Ok::<_, motionlink_compax::Error>(seen)
    };
    // Race the move against the readings (what `tokio::select!` does, written out with std's poll_fn).
    let mut moving = Box::pin(client.move_to(one, &request));
    let mut readings = Box::pin(readings);
    let raced = std::future::poll_fn(|cx| {
        if let Poll::Ready(moved) = moving.as_mut().poll(cx) {
            return Poll::Ready(Err(moved));
        }
        readings.as_mut().poll(cx).map(Ok)
    })
    .await;
    let during = match raced {
        Ok(seen) => seen?,
        Err(moved) => return Err(format!("the move ended by itself: {moved:?}").into()),
    };
    drop(moving);
    drop(readings);
    // The move's future was dropped when the readings ended: its operation is cancelled, and the session
    // stops the axis it started. Wait (bounded) until it has confirmed that.
    for _ in 0..200 {
        if client.started().is_empty() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    if !client.started().is_empty() {
        return Err("the stop was not confirmed within a second".into());
    }
    let stopped_at = client.read_position(one).await?.units();
    let s16 = client.read_s16(one).await?;
    let s17 = client.read_s17(one).await?;
    tokio::time::sleep(Duration::from_millis(200)).await;
    let later = client.read_position(one).await?.units();
    println!(
        "after the move's future was dropped: drive 1 at rest at {stopped_at} (still {later} 200 ms later), \
         switched off (O0={}), command active: {}",
        s16.o0_state(),
        s17.contains(S17Flag::CommandActive)
    );
    let report = client.close().await?;
    println!("closed: {report}");
    Ok(Summary { during, stopped_at, later, o0: s16.o0_state(), moving: s17.contains(S17Flag::CommandActive) })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A tokio runtime made by hand (what `#[tokio::main]` would write).
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    runtime.block_on(async { run().await.map(|_| ()) })
}
