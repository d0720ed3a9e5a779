//! The clients: [`Client`] for blocking callers and, with the `tokio` feature, `AsyncClient` for async
//! ones. Both are thin typed methods over a [`Driver`](motionlink_link::driver::Driver) running the
//! [`Session`](crate::Session), so they have the same operations and the same safety: a motion that cannot
//! go on is halted and the error says whether the module confirmed it; a cancelled motion (a signal, a
//! dropped future) is halted; closing halts what the session started and switches off the watchdogs it
//! switched on, bounded in time.
//!
//! ```
//! use motionlink_link::pipe::{EmulatorHost, PipeConfig};
//! use motionlink_link::clock::{Clock, ManualClock};
//! use motionlink_powercube::client::{Config, Client, MoveSpec, PortLink};
//! use motionlink_powercube::model::{Address, Position, StateFlag, Velocity};
//! use motionlink_powercube::Emulator;
//! use std::time::Duration;
//!
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let host = EmulatorHost::new(Emulator::new(&Default::default()), clock.shared(), PipeConfig::paced(9_600));
//! let client = Client::with_link(PortLink::Rs232(Box::new(host.connect().0)), clock.shared(), Config::rs232()).unwrap();
//! let joint = client.module(Address::new(1).unwrap());
//! joint.home_and_wait(Duration::from_secs(10), &mut |_| {}).unwrap();
//! let spec = MoveSpec { vel: Some(Velocity::rad_per_s(0.5)), ..MoveSpec::to(Position::rad(0.5)) };
//! let report = joint.move_to(&spec, &mut |_| {}).unwrap();   // limits, read-backs, the final position
//! assert!(report.state.contains(StateFlag::RampEnd));
//! assert!((joint.position().unwrap().value() - 0.5).abs() < 1e-3);
//! client.close().unwrap();
//! ```

/// The session's state as both clients read it (each has `session`): one list of getters for both.
macro_rules! session_state {
    () => {
        /// True when this session can arm the watchdog (CAN; RS232 unless
        /// [`Config::watchdog_on_rs232`](crate::session::Config::watchdog_on_rs232) is false). A host that dies then stops the modules whose watchdog it switched on within 50 ms.
        pub fn watchdog_reliable(&self) -> bool {
            self.session(|s| s.watchdog_reliable())
        }

        /// Stops refreshing the watchdog on purpose and marks the session failed (see
        /// [`Session::abandon_watchdog`](crate::Session::abandon_watchdog)).
        pub fn abandon_watchdog(&self) -> bool {
            self.session(crate::Session::abandon_watchdog)
        }

        /// True if this session switched the watchdog of `address` on (or may have) and still refreshes it.
        pub fn watchdog_armed(&self, address: crate::model::Address) -> bool {
            self.session(|s| s.watchdog_armed(address))
        }

        /// True while the session refreshes the watchdog.
        pub fn watchdog_served(&self) -> bool {
            self.session(|s| s.watchdog_served())
        }

        /// The last failure of the refresh, if any.
        pub fn watchdog_error(&self) -> Option<String> {
            self.session(|s| s.watchdog_error())
        }

        /// True once the session has failed (see [`Session::failed`](crate::Session::failed)).
        pub fn failed(&self) -> bool {
            self.session(|s| s.failed())
        }

        /// Modules known to exist: every address that answered this session.
        pub fn known(&self) -> Vec<crate::model::Address> {
            self.session(|s| s.known())
        }

        /// Modules this session set in motion and has not seen stop.
        pub fn started(&self) -> Vec<crate::model::Address> {
            self.session(|s| s.started())
        }
    };
}
use session_state;

#[cfg(feature = "tokio")]
mod asynch;
mod blocking;
mod calls;
mod port;
#[cfg(test)]
mod tests;

#[cfg(feature = "tokio")]
pub use asynch::{AsyncClient, AsyncModule};
pub use blocking::{Client, Module};
pub use port::PortLink;

pub use crate::error::{Error, RefreshTiming, RoundTripRange, StopOutcome};
pub use crate::model::WATCHDOG_TIMEOUT;
pub use crate::session::{
    Config, Guard, HaltReport, HomeReport, ModuleInfo, ModulesAt, MotionEnding, MotionReport, MotionSpec, MoveReport,
    MoveSpec, Progress, Readback, ScanEntry, SetpointReport,
};
