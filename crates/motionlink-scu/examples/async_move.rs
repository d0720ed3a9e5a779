//! The async client on tokio: positions are read while a move runs in another task, then the move is
//! cancelled by dropping its future (the task is aborted), and the actuator is seen at rest: the session
//! stopped the motion it had started (fast RS, confirmed by the status).
//!
//! Runs against an emulated unit in this process, paced at 38400 baud, on the real clock:
//!
//! ```text
//! cargo run -p motionlink-scu --example scu_async_move --features tokio
//! ```

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::RealClock;
use motionlink_scu::model::{Actuator, PositionCounts, Speed};
use motionlink_scu::{AsyncClient, Config, Emulator, FunctionMap, SimConfig};

/// What the example saw.
#[derive(Debug)]
pub struct Seen {
    /// Positions of A1 read while the move ran.
    pub reads: Vec<PositionCounts>,
    /// Where A1 came to rest after the move was cancelled (read twice, 300 ms apart).
    pub rest: (PositionCounts, PositionCounts),
    /// Whether the emulated unit still moved A1 after that.
    pub unit_moving: bool,
    /// Functions the session still counts as started (RE without RS).
    pub started: Vec<motionlink_scu::model::Function>,
}

/// The example: returns what it saw.
pub async fn run() -> Result<Seen, Box<dyn std::error::Error + Send + Sync>> {
    let clock = RealClock::shared();
    let unit = EmulatorHost::new(Emulator::new(SimConfig::default())?, Arc::clone(&clock), PipeConfig::paced(38_400));
    let watch = unit.clone();
    let config = Config { function_map: FunctionMap::scp11(), ..Config::default() };
    let connector = unit.connector();
    let client = Arc::new(AsyncClient::with_connector(connector, clock, config).await?);
    let a1 = Actuator::new(1).ok_or("actuator 1")?;
    let full = Speed::percent(100).ok_or("100 %")?;

    // The move runs in a task of its own (800 counts at 110 counts/s: about 7 s).
    let mover = {
        let client = Arc::clone(&client);
        tokio::spawn(async move { client.move_to(a1, PositionCounts(800), full, None).await })
    };
    // Meanwhile this task reads where A1 is.
    let mut reads = Vec::new();
    while reads.len() < 6 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        reads.push(client.position(a1).await?);
    }
    // Cancel the move: the aborted task drops its future, and the session stops the motion it started.
    mover.abort();
    let _ = mover.await;
    // The stop (fast RS) goes out before anything else; the first status read after it sees A1 at rest.
    let mut moving = true;
    for _ in 0..20 {
        moving = client.status1(a1).await?.moving();
        if !moving {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    if moving {
        return Err("A1 still moves after the move was cancelled".into());
    }
    let first = client.position(a1).await?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let second = client.position(a1).await?;
    let seen = Seen {
        reads,
        rest: (first, second),
        unit_moving: watch.with_device(|u| u.is_moving(a1)),
        started: client.started(),
    };
    // Closing stops what the session started (and returns those functions).
    match Arc::try_unwrap(client) {
        Ok(client) => client.close().await?,
        Err(_) => return Err("the client is still shared".into()),
    };
    Ok(seen)
}

fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    // A tokio runtime made by hand (what `#[tokio::main]` would write).
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    runtime.block_on(async {
        let seen = run().await?;
        let reads: Vec<i32> = seen.reads.iter().map(|p| p.get()).collect();
        println!("positions of A1 read while it moved: {reads:?} counts");
        println!("the move was cancelled by dropping its future; A1 came to rest at {}", seen.rest.0);
        println!("300 ms later A1 is at {}; the unit moves it: {}", seen.rest.1, seen.unit_moving);
        println!("functions still started: {:?} (every RE got its RS)", seen.started);
        Ok(())
    })
}
