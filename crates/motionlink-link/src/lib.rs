//! Bytes and frames in motion, shared by every motionlink device family.
//!
//! - [`can`]: CAN frames and links (SocketCAN, SLCAN, in-memory bus).
//! - [`capture`]: taps on links, capture files that `decode` reads back, live traces.
//! - [`chunk`]: what passes on a link (bytes or a CAN frame) and which way: one vocabulary for sessions,
//!   taps, transcripts and describers.
//! - [`cancel`]: a cancellation flag for long actions (Ctrl-C).
//! - [`clock`]: the [`Clock`] every timeout, period and emulator reads; real and manual.
//! - [`error`]: the one classification of errors every family uses.
//! - [`session`]: the sans-IO [`session::Session`] every family's protocol logic implements.
//! - [`exec`]: the one executor of every family's session operations (`async fn`s on the session's clock).
//! - [`driver`]: the drivers that run a session over a link, for blocking and async callers.
//! - [`hex`]: bytes as hex text and back.
//! - [`flags`], [`table`]: the one flag-set and the one parameter-table mechanism of every family.
//! - [`describe`]: the one decoder signature of every family (decode, wire trace, captures).
//! - [`link`]: the [`Link`] trait, a byte stream with read timeouts, and its errors.
//! - [`serial`], [`tcp`]: links to real ports and serial-over-TCP gateways; pty pairs for tests.
//! - [`portlock`]: who holds a port (a lock file naming the holder), and a stop from another process.
//! - [`pipe`]: in-memory links with baud-rate pacing and fault injection, and in-process emulators.
//! - [`emulator`]: the [`emulator::Emulator`] trait and servers for `motionlink sim`.
//! - [`url`]: the `--port` syntax.
//! - [`transcript`]: a recording link wrapper.
//! - [`probe`]: the shared pieces of a commissioning report (`motionlink probe`): checks, link measurements,
//!   a USB serial adapter's latency timer, the baud-rate search.
//! - [`devices`]: the configuration file of named devices (`devices.toml`), and where a port comes from.
//! - [`profile`]: device profiles (`profiles.toml`), which let a later session skip the probes.

#![warn(missing_docs)]

pub mod can;
pub mod cancel;
pub mod capture;
pub mod chunk;
pub mod clock;
pub mod describe;
pub mod devices;
pub mod driver;
pub mod emulator;
pub mod error;
pub mod exec;
pub mod flags;
pub mod hex;
pub mod link;
pub mod pipe;
pub mod portlock;
pub mod probe;
pub mod profile;
pub mod result;
pub mod serial;
pub mod session;
pub mod table;
pub mod tcp;
pub mod transcript;
pub mod url;

pub use clock::{Clock, ManualClock, RealClock, SharedClock, Signal, Timestamp};
pub use link::{Link, LinkError, SerialSettings};

/// serde, for the flag words that [`flag_set!`] generates in the family crates (they serialise as
/// [`flags::WordView`]).
#[doc(hidden)]
pub use serde;
