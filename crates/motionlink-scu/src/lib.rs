//! Ewellix / Schaeffler SCU control unit over RS232: the codec, the data list, the protocol as a sans-IO
//! session that keeps the unit's watchdog fed and stops what it started, blocking and async clients that run
//! it, and an emulator of the unit.
//!
//! Layers, each importing only from those above it in this list:
//!
//! - [`wire`]: telegrams to and from bytes, CRC-16/XMODEM, incremental decoders that resynchronise. No I/O,
//!   no clock, no allocation.
//! - [`model`] and [`value`]: the data list as one shared [`Table`](motionlink_link::table::Table)
//!   ([`model::TABLE`]), functions, Safety_ID, the named bit sets and the 32-bit error code as shared flag
//!   words, units as types ([`model::Speed`]: percent and counts/s are different types; [`model::PositionCounts`]
//!   for every position of the clients, their reports and errors); typed values with their ranges. [`describe`]: the family's [`Describe`](motionlink_link::describe::Describe).
//! - [`error`]: [`Error`], with the unit's codes as values and its class for every front end.
//! - [`session`]: the protocol as a sans-IO [`Session`] (bytes in with the time; bytes out, the next deadline,
//!   events): request matching, repetitions, the RC keepalive, every multi-step operation as an `async fn`
//!   run by the one executor of `motionlink-link`.
//!   Tested with no link at all.
//! - [`client`]: [`Client`] (blocking) and, with the `tokio` feature, `AsyncClient` run the session over a
//!   [`Link`](motionlink_link::Link) on the shared driver: the same operations and the same safety.
//! - [`args`]: every argument of the front ends as a validated type, one rule and one message each;
//!   [`results`]: every report serialises with the names the command line's `--json` shows.
//! - [`sim`]: the unit ([`Emulator`]) as a sans-IO state machine with a physical model of its actuators.
//!
//! **Closing.** [`Client::close`] (and `AsyncClient::close`) ends the session: RS for every function it
//! started (motions fast), the status of every actuator until none moves, then RA, and returns the
//! outcome. Dropping a client does the same, waiting at most [`Config::close_bound`] (5 s by default; a
//! dead link takes about 0.6 s: one short try of RS and of RA); after that the stop is reported
//! unconfirmed and the unit's own watchdog (500 ms) is what stops the drives. A dropped async future
//! cancels its operation, which stops any motion it started.
//!
//! ```
//! use motionlink_link::{pipe::{EmulatorHost, PipeConfig}, link::Link, ManualClock, Clock};
//! use motionlink_scu::{model::{Actuator, PositionCounts, Speed}, Client, Config, Emulator, SimConfig};
//!
//! // A virtual clock: ten seconds of device time take a few milliseconds.
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let unit = EmulatorHost::new(Emulator::new(SimConfig::default())?, clock.shared(), PipeConfig::paced(38_400));
//! let client = Client::with_connector(unit.connector(), clock.shared(), Config::default())?;
//! let a1 = Actuator::new(1).unwrap();
//! // Positions are `PositionCounts`, speeds `Speed` (percent or counts/s): a bare number is neither.
//! let report = client.move_to(a1, PositionCounts(400), Speed::percent(80).unwrap(), &Default::default())?;
//! assert_eq!(report.position_counts, PositionCounts(400)); // read after the unit reported the end of the motion
//! assert!(report.actuators.iter().all(|a| a.difference_counts().abs() <= 5 || !a.moved));
//! assert_eq!(client.position(a1)?.get(), 400);
//! assert!(client.status1(a1)?.available() && !client.statuses()?[0].moving()); // flag words, by name
//! client.close()?; // RS for anything still started, then RA
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Decisions
//!
//! Where the two editions of the manual are silent or contradict each other, this crate decided as follows
//! (the field notes' decisions are followed too: one-byte RO, bit n is mask `1 << (n - 1)`, the bytes of the
//! RT example are the truth):
//!
//! - **Reply timeout and retries.** The manual allows a unit 2000 ms to reply, and the session gives RO that
//!   long. But the unit's watchdog expires 500 ms after the last RC, and no RC can go out while a reply is
//!   awaited, so in remote mode a reply is awaited at most 1000 ms: a unit silent that long has stopped its
//!   drives and left remote mode anyway. A request is sent again when not one byte of its reply came within
//!   [`Config::retry_after`] (150 ms, or twice the measured round trip, or half a shorter reply
//!   timeout), then after 300, 600 ms
//!   of silence; the reply to any sending is accepted, the others are read and dropped. Before the first
//!   repetition the client sends 256 zero bytes, which complete a telegram whose corrupted length byte left
//!   the unit waiting (it answers CSE) and are otherwise skipped as garbage. After a whole request without a
//!   byte of reply the line counts as silent: keepalives pause, and each request gets one sending and 300 ms.
//! - **RE is repeated** like the other requests (after silence, a corrupt reply, a CSE or PCE): every RE names
//!   an absolute destination (an end, a stored position, the remote position) or switches a function on, so
//!   a second sending has the effect of the first. RS after a failed RE is sent in any case. A unit that took
//!   the first sending may refuse the second with PE (it wants the RS the manual asks for after every RE
//!   first): a repeated RE of a motion function refused so, even after the RC and once more, gets the soft
//!   RS and then the RE again (with a warning; a stream sends RS before each later RE).
//! - **PE from a unit that left remote mode** (a watchdog expiry, a reset, someone else's RA): the client
//!   sends an RC and tries once more. Still PE: the unit ended remote mode (with Safety_ID 0 it takes RC but
//!   no remote motion until RO); the caller gets `RemoteEnded`, and the client never sends RO by itself:
//!   [`Client::reopen`] is the caller's decision. Only the end of a session opens remote mode to
//!   send the RS every RE needs, then RA. Accepted after the RC (a unit that, after a lapse with Safety_ID
//!   1 or 2, refuses commands only until the next RC re-arms its watchdog: no edition says so, emulator
//!   variant `rc-rearms-watchdog`; by chapter 5 a unit deactivates remote mode and refuses the RC too): the
//!   session goes on; a caller with functions started gets `RemoteEnded` once (their motion was stopped by
//!   the unit), and they get their RS.
//! - **Which actuators a function drives** is the unit's parameterisation, which the data list does not show.
//!   The caller gives it ([`FunctionMap`]; presets for SCP11, TLT and LIFTKIT); where it is not given,
//!   a move writes the target into every connected actuator's remote position and reports the actuators that
//!   moved, rather than guessing; a move or stream given targets for some actuators holds the other
//!   connected ones (their remote positions written with where they stand).
//! - **The stroke** of an actuator, for refusing targets before anything moves, is read from the virtual
//!   limits of its UserPositionData (0x2001..0x2006, "Position_Virtual_Limit_In/Out"), the only limits in the
//!   data list; both 0 means none are set. The emulator stops every motion at the stroke ends and at the
//!   virtual limits. A unit that refuses UserPositionData: see "Beyond the manual" below.
//! - **In-position tolerance**: 5 counts by default (1.5 mm on a TLT column of about 3225 counts per metre);
//!   real columns read a few counts off after homing.
//! - **Error bits reset on the next motion** (14, 15..20, 21) are cleared from Error_Code 1 when an RE of a
//!   motion function with a direction other than 0 ("undefined direction, no motion") is accepted, or the
//!   hand switch starts a motion; the history keeps them.
//! - **Speed changes during motion** ("the speed can be changed during motion") apply to the running remote
//!   motions of the function whose remote speed is written; a new remote position takes effect with the next
//!   RE, so streamed setpoints are RT and RE each time.
//! - **Which errors.** RT of an index that is not remote data (0x3xxx), an unknown index, or a value out of
//!   range (speed above 100 % or 1000 counts/s, a cyclic object writing read-only data) is PDE; data of the
//!   wrong length is PCE; an RE of a function that drives no actuator, or of a motion function while the
//!   emergency stop is on or while an error stands whose reaction is that motions are not performed (bits
//!   8, 13, 24..32: "Motion not executed", "Motions not performed (or stopped)", E 4.6 Table 7, S 4.5), is
//!   PE, "command not possible with SCU mode/state" (emulator variant `ack-without-motion`: acknowledged,
//!   and nothing moves). The emulator keeps such an error standing until it is restarted.
//! - **A reset of the unit** (error bits 1..5, "the control unit carries out a reset") ends remote mode and
//!   initialises the remote data with their presets, as the data list says of them ("Initialized after
//!   reset with preset values"): remote speeds the function speed from the configuration, remote positions
//!   memory 1 / user 1 of UserPositionData, cyclic objects -1.
//! - **Unknown commands.** A telegram `R?` with an unknown letter ends where its CRC matches (within 64
//!   bytes) and is answered ICE with its letters repeated; other bytes that start no telegram are skipped.
//! - **Safety_ID after a watchdog expiry.** 0: everything stops, and only RC, RA and RO are accepted until a
//!   new RO (the RO row, E 4.1 / S 4.1). 1: everything stops; 2: only remote motions stop; with both the
//!   unit deactivates remote mode, as chapter 5 says of the watchdog ("the SCU will stop all drives in
//!   motion and deactivate the remote mode", E 5.1 / S 5), so RG, RT, RC, RE and RS are refused with PE
//!   until a new RO. Neither edition says that an RC re-arms the watchdog; a firmware that does (refusing
//!   commands only until the next RC) is the emulator variant `rc-rearms-watchdog`. In every case error bit
//!   22 enters the error history.
//! - **Cyclic objects.** "The first 6 bytes (para[0..5])" of the `UINT16[12]` definition means the first six
//!   entries: six write indices, six read indices, -1 (0xFFFF) unused. An RC naming a cyclic object answers
//!   with ctp and read data (ctp 0 when nothing is read); an RC with object -1 answers with the status alone.
//! - **Groups.** RG of a group index (0x0010, 0x0080 ...) returns its members' values in index order; 0x0080
//!   includes 0x008F and 0x00B0 includes 0x00BF; the collection indices 0x1000, 0x2000 and 0x3000 return
//!   every entry of their collection (0x2000: all six UserPositionData structures; 0x3000: the cyclic
//!   objects, remote speeds and remote positions), but 0x0000 returns only the firmware and configuration
//!   texts (0x0001, 0x0002): the whole 0000 collection is two dozen groups that have their own indices, and
//!   the Schaeffler edition prints 0000 as the secondary index of those two (S 338; the Ewellix edition
//!   leaves that cell blank, E 361).
//!   RT may write whole 0x3xxx groups and the 0x3000 collection, all or nothing.
//!
//! # Beyond the manual
//!
//! What the client relies on that the manual does not say in so many words is probed on the unit in use the
//! first time a check depends on it (a read, or an RC that only reads), remembered for the session
//! ([`Client::capabilities`]), and said once in a warning when the unit does not behave so; the operation
//! then runs in the manual's plain form and a [`session::MoveReport`] or [`session::SetReport`] says in
//! `verified` / `not_verifiable` what it could not check. A unit that shows a real discrepancy (a value that
//! reads back different) is still refused. Each behaviour has an emulator variant ([`sim::Variant`]):
//!
//! - **Grouping indices** (0x0010, 0x0170, 0x00A0, 0x00D0): refused with PDE, every group is read entry by
//!   entry from then on (`no-groups`).
//! - **UserPositionData** as the stroke of targets: refused, targets are checked against
//!   [`Config::stroke_limits`] only, and a move without them says that its target was not checked
//!   (`no-user-positions`).
//! - **Cyclic objects** (the session's CyclicObj 5 carried by the keepalive RC): refused, motions and samples
//!   are read with RG (`no-cyclic-objects`).
//! - **Reading remote data back** after RT: refused, writes are checked by the unit's ACK only, and say so
//!   (`no-remote-readback`).
//! - The RC reply without a cyclic object, the status alone or with ctp 0: both are taken (`rc-empty-data`);
//!   a unit that answers only the second telegram after a silence is sent it again (`sleepy`); error bits that
//!   stay after the next motion, positions a few counts below the In end after homing, a unit that refuses a
//!   second RE without RS: no check depends on the first two, and the third ends a stream with the unit's PE
//!   (`sticky-errors`, `in-end-undershoot`, `re-needs-rs`); a motion bit that rises 0.4 s after the RE is
//!   waited for ([`Config::start_grace`], 1 s) before an actuator still standing is judged (`late-motion-bit`).
//! - A unit that acknowledges an RE while an error stands after which motions are not performed, and moves
//!   nothing: a move is judged where the actuator stands once [`Config::start_grace`] has passed, and fails
//!   naming the error code (`ack-without-motion`). A unit whose next RC re-arms its watchdog after a lapse
//!   with Safety_ID 1 or 2: see "PE from a unit that left remote mode" above (`rc-rearms-watchdog`).
//! - **RA** fast-stops remote motions that are still running: a motion nobody can stop any more is worse.
//! - **Switching functions** (F11 buzzer, F17/F18 binary outputs, F20 emergency stop, F21/F22 LEDs): after the
//!   unit acknowledged their RE or RS, the entry that shows them is read back ([`model::SwitchStatus`],
//!   [`Client::switch`], a run's [`session::RunReport`]) until it shows the state asked for, at most
//!   [`Config::start_grace`]. The buzzer (0x0140) and binary output 1 (0x0110 bit 0) the manuals name: the
//!   other state shown is [`Error::SwitchNotShown`]. Binary output 2 as bit 1 of 0x0110 (the manuals name it
//!   "Binary Output 1" again), F21 and F22 as the hand switch's LED 1 and 2 (0x0120), the emergency stop as
//!   every motion function locked in Lock Status (0x0162) are readings: the session trusts such an entry once
//!   it has seen it show the function on and off around its acknowledged RE and RS (the first switch is the
//!   probe; the entry is read before it too, before the RE of F20 only when the line has room at once); one
//!   that does not follow says `verified: false` for the rest of the session (`switch-status-unshown`), as does
//!   a unit that refuses the entry (PDE).
//! - **Where the editions differ in a text**, the reading that fits the rest of the table wins (both
//!   editions' words, with line numbers, are in docs/assumptions.md, "Where the two editions differ"). Battery
//!   Mains bit 2: the Ewellix edition says "0/1: charging control on/off", the Schaeffler edition "charge
//!   controller off/on"; every other bit of the entry reads 0 = off / absent, so bit 2 set means the charge
//!   controller is on (Schaeffler; on a unit that behaves as the Ewellix edition says, a set bit means off). Error bit 30: the Schaeffler edition repeats bit 29's "calibration data",
//!   the Ewellix edition has "HW settings", which no other bit covers (Ewellix). Error bit 32: "IDF operating
//!   system error" (Ewellix) rather than the Schaeffler edition's cause column, which repeats the reaction.
//!   F22: "LED2" (Ewellix); the Schaeffler edition repeats F21's "LED1", and 0x0120 has an LED 2.
//! - **Typos of the Ewellix edition** (0x0095 twice for Cumulated_Stroke A6, 0x00E6 for Speed A1) follow the
//!   Schaeffler edition: 0x0096 and 0x00F1.
//! - **Watching a motion through the keepalive.** A running motion is watched through the RC: the session
//!   defines CyclicObj 5 (0x3005; [`MovePolling`] chooses another or reads) to read status 1, the position
//!   and the current of every actuator and Error_Code 1 (0x0170, 0x0010, 0x00A0, 0x00D1: 46 bytes), writes
//!   and reads back the definition and probes one RC carrying it before its first move or sample, and while a
//!   motion or a watch ([`Client::watch`]) runs the RCs carry it: each exchange both feeds the watchdog and
//!   reads the state, so a link whose round trips take 300 ms still keeps the unit alive during a move and
//!   can be watched. A unit that refuses the definition, its read-back or the RC is polled with reads; so is
//!   a session whose keepalive carries the caller's own cyclic object.
//! - **Room on the line.** The next RC must go out at most 400 ms after the last (the watchdog's 500 ms, less
//!   100 ms for jitter and an estimate that is short). A request other than RC goes out only if its reply is
//!   expected back before then, by the longest round trip measured lately; one that finds no room within
//!   1000 ms fails ([`Error::NoRoom`]) rather than let the watchdog expire. Stops (RS), RA and RO never wait;
//!   the RS that ends a move that reached its target waits for room at most 1000 ms and then goes anyway.
//! - **A watch on a link too slow for its cyclic object's definition** (RC, RT, RC reach the unit two round
//!   trips apart, beyond 500 ms, and the manual gives no other form) writes it anyway, only while the session
//!   has started nothing, and lets the watchdog lapse once (the unit records error bit 22 and stops the
//!   motions its Safety_ID says); RO and an RC carrying the object then open remote mode again, and that RC's
//!   read data is the first sample and the check ([`session::ClientStats::deliberate_lapses`]).
//! - **Captures.** An RO ACK is byte for byte an RO request with Safety_ID 6; in a capture that mixes both
//!   directions the reply reading wins.
//! - **CRC.** CRC-16/XMODEM comes from the `crc` crate (its slice-by-16 tables); the codec walks them eight and
//!   four bytes at a time, because the crate's own loop takes every byte after the last whole 16-byte block one
//!   at a time and SCU telegrams are short. The tests check it against the crate for every length and against
//!   the manual's table.
#![warn(missing_docs)]

pub mod args;
pub mod client;
pub mod config;
pub mod describe;
pub mod error;
pub mod model;
pub mod probe;
pub mod results;
pub mod session;
pub mod sim;
pub mod value;
pub mod wire;

pub use client::{ending, port_connector, Client, Ending, FollowReport, Follower, MoveOptions, SetpointStream};
#[cfg(feature = "tokio")]
pub use client::{AsyncClient, AsyncSetpointStream};
pub use config::{Config, FunctionMap, MovePolling, StrokeLimits};
pub use error::Error;
pub use session::{Op, Output, Progress, Session};
pub use sim::{Emulator, FirmwareVariant, SimConfig, Variant};
