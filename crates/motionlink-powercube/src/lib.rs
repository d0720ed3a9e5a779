//! Schunk / Amtec PowerCube modules: the data exchange protocol of the manual "Data exchange with
//! PowerCube" on its three carriers (RS232, CAN, Profibus-DP), a client for a bus of modules, and an
//! emulator of such a bus.
//!
//! Layers, bottom to top, each using only those below it:
//!
//! - [`wire`]: the sans-IO codec. [`wire::Payload`] (`[CommandID][ParamID|MotionID][data]`, at most 8
//!   bytes), the RS232 frame with TELID, BCC and DLE escaping and an incremental decoder that resynchronises
//!   on STX ([`wire::rs232`]), CAN identifiers ([`wire::can`]) and the Profibus-DP process images
//!   ([`wire::profibus`]). No I/O, no clock, no allocation.
//! - [`model`]: the vocabulary. The parameter table ([`model::Param`], rows of the shared
//!   [`Table`](motionlink_link::table::Table): [`model::PARAMS`]), the 18 motion modes ([`model::MotionId`],
//!   [`model::Motion`]), every flag word through the shared `flag_set!` ([`model::CubeState`],
//!   [`model::ConfigWord`] ...), typed commands, acknowledges and broadcasts ([`wire::Request`],
//!   [`wire::Reply`], [`model::Broadcast`]), and quantities with their unit ([`model::Position`] in rad, m or
//!   explicitly the module's own unit; [`model::Address`] checked once).
//! - [`session`]: the protocol as a sans-IO [`Session`]: request matching, retries of reads only, the
//!   watchdog refresh on its 20 ms grid, and every multi-step operation ([`session::Op`]: checked moves,
//!   homing, scans, arming and disarming watchdogs, the close sequence that stops what was started) as a
//!   state machine, tested with a manual clock and no link.
//! - [`client`]: [`Client`] (blocking) and, with the `tokio` feature, `AsyncClient`: the same typed
//!   operations over [`motionlink_link::driver`] running the session; closing stops what was started,
//!   bounded in time.
//! - [`sim`]: [`Emulator`], modules at configurable addresses with a physical model of the axis, as an
//!   [`Emulator`](motionlink_link::emulator::Emulator) (RS232 framing) and a
//!   [`CanEmulator`](motionlink_link::can::CanEmulator).
//! - [`describe`]: [`Describe`](motionlink_link::describe::Describe) for captures, the wire trace and
//!   `motionlink decode powercube`.
//! - [`Error`]: one error type, classified ([`Classify`](motionlink_link::error::Classify)).
//!
//! ```
//! use motionlink_link::can::{CanBus, CanBusConfig};
//! use motionlink_link::clock::{Clock, ManualClock};
//! use motionlink_powercube::client::Config;
//! use motionlink_powercube::model::Address;
//! use motionlink_powercube::sim::SimConfig;
//! use motionlink_powercube::{Client, Emulator, PortLink};
//!
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let sim = Emulator::new_can(&SimConfig::with_addresses(&[1, 2, 3]).unwrap());
//! let can = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
//! let bus = Client::with_link(PortLink::Can(Box::new(can.connect())), clock.shared(), Config::can()).unwrap();
//! let found = bus.scan().unwrap();
//! assert_eq!(found.len(), 3);
//! let modules: Vec<Address> = found.iter().map(|e| e.address).collect(); // 1, 2, 3
//! bus.enable_watchdog(&modules).unwrap(); // refreshed by the session from now on
//! let positions = bus.positions(&modules); // three requests out, three acknowledges in, any order
//! assert!(positions.iter().all(|p| p.is_ok()));
//! bus.close().unwrap(); // watchdogs off again, Config words as they were
//! ```
//!
//! # Decisions
//!
//! Where the manual contradicts itself or is silent, this crate decides as follows (each is tested).
//!
//! - **BCC.** `(s + (s >> 8)) & 0xFF`, `s` the 16-bit sum of TELID and data; the manual's examples agree
//!   (Home to module 17 is `02 06 21 01 28 03`). DLE escaping covers TELID, data and BCC.
//! - **BCC checking.** The modules do not check the BCC "for compatibility reasons": the emulator accepts a
//!   wrong BCC unless told to be strict (`--strict`); the client always checks the BCC of what it receives
//!   and reports a mismatch as [`Error::Corrupt`] (reads are then retried).
//! - **TELID length.** The manual's RS232 acknowledge examples carry length 6 for 3 data bytes. The
//!   emulator sends the true length and, as the manual says, ignores commands whose length does not match;
//!   the client accepts acknowledges with the true length or that one slip (6 for 3); any other mismatch
//!   is a corrupt answer.
//! - **CAN identifiers.** The DLC is the data length; "+ number of data bytes" in the manual's formulas is
//!   not added to the identifier. Extended motion acknowledges come on the acknowledge identifier
//!   `0x0A0 + address`, whatever the manual's last CAN table shows (`0x0f1`).
//! - **Broadcasts on RS232.** The manual lists broadcasts for CAN only (4.1.2). Schunk's own library,
//!   libm5api, sends them over RS232 to module address 0 with the command followed by 0x00 (haltAll is
//!   `02 04 10 82 10 82 00 08 03`), and real modules act on them: the client sends that form
//!   ([`model::BroadcastForm::Padded`]) on RS232 and the manual's one-byte form on CAN; the emulator and
//!   `decode` take both forms, on both carriers. The padded form has a second merit: a bit flipped in its
//!   address cannot make it the life sign of one module (`07` alone to one module toggles its watchdog;
//!   `07 00` to one module is no command). The watchdog is therefore armed on RS232 by default
//!   ([`session::Config::watchdog_on_rs232`] switches that off). Whether a module takes that form is
//!   found out the first time its watchdog is armed on RS232 (it must stay online past its 50 ms); one
//!   that ignores it has its watchdog switched off again and reset, and its motions run without one, each
//!   result saying so ([`session::ModuleFindings`]).
//! - **Inc twins.** Whether TargetVelInc / TargetAccInc / TargetPosInc follow TargetVel / TargetAcc /
//!   TargetPos (and a float motion's target) is found out per module and pair the first time a write
//!   depends on it (the twin read before and after the write; see the session's `twins` steps), and
//!   remembered: a module that keeps them apart gets the manual's plain writes, reported as not verified
//!   ([`session::Readback`], [`session::MoveReport`]); a twin that follows but shows another value is
//!   refused. The emulator's firmware variants ([`sim::Variant`]) model the other readings of what the
//!   manual leaves open. A broadcast Halt on RS232 still does not
//!   count as stopping anything: the session asks each module it started on drop and halts it by address.
//! - **What a broadcast sets in motion.** Home and StartMotion count as starting the modules the session
//!   knows exist ([`Session::known`]: every address that has answered it), not all 31 addresses: a drop
//!   then asks only those. A module that never answered and does not answer the drop's question is taken as
//!   absent (no broadcast Halt of the whole bus for it); a known module that stops answering still gets one.
//! - **Life sign.** The individual `0x07` (switch the watchdog on, and off when sent again) is acknowledged
//!   `[0x07]` by the emulator like every one-byte command. The acknowledge is the only confirmation the
//!   manual offers (no flag shows an online watchdog): silence is [`Error::WatchdogUnconfirmed`]
//!   naming the module, and the life sign is never repeated (a repeat could switch the watchdog the wrong
//!   way). Such a module is refreshed while the session serves; `disable_watchdog` stops the refresh and
//!   observes it (an online watchdog expires: STATE_COMM_ERROR after 2 × 50 ms) instead of toggling it.
//! - **Watchdog expiry** raises STATE_COMM_ERROR, STATE_HALTED and STATE_ERROR (the manual: "enter an error
//!   state"; Profibus shows STATE_ERRORM4). A Reset re-arms it: without refreshes it expires again 50 ms
//!   later. A guarded motion whose module reports it ends with [`Error::WatchdogExpired`], which says from
//!   the session's own record of its refreshes whether one went out more than 50 ms after the one before
//!   (the host was not scheduled in time) or all went out in time (the line or the module lost them).
//! - **CAN-only Config flags.** CONFIGID_MOD_SYNC_MOTION and CONFIGID_MOD_DISABLE_ACK are "valid only for
//!   CAN-Bus": the emulator stores them on RS232 but ignores them there.
//! - **Change baud rate.** The emulator decodes the broadcast and records the rate (`Emulator::can_baud`,
//!   `SimModule::can_baud`); the in-memory link keeps its pace (a real bus needs every node and the host to
//!   switch together).
//! - **Watchdog and the Config word.** [`Client::enable_watchdog`] sets CONFIGID_MOD_WATCHDOG_ENABLE
//!   only where it is clear, and remembers the word; [`Client::disable_watchdog`] first switches the
//!   watchdog offline (a second life sign), then clears that flag again where the session set it, leaving
//!   every other bit as it is now, so a session that ends normally leaves the Config word as it found it.
//!   A session that dies cannot: its modules halt with STATE_COMM_ERROR, their watchdog stays online and
//!   the flag stays set (harmless: the watchdog only runs after a life sign).
//! - **Arming an expired watchdog.** The online state of a watchdog cannot be read and the life sign
//!   toggles it, so the client never guesses: `enable_watchdog` refuses a module that shows
//!   STATE_COMM_ERROR (its watchdog is most likely online, left by a host that died) with
//!   [`Error::Device`] before changing anything. [`client::Module::reset_and_release_watchdog`]
//!   follows the manual's first way to restart: Reset; if STATE_COMM_ERROR comes back within 100 ms (online
//!   and nobody refreshes it), a life sign switches the watchdog offline and a second Reset clears it. A
//!   watchdog that another live host serves is therefore left alone. `motionlink powercube reset` does this.
//! - **State flags.** STATE_POW_INTEGRAL-ERR is bit 23 (0x00800000; the table prints 0x00080000).
//!   STATE_LOGIC_VOLT and STATE_POW_SETUP_ERR are both bit 27: both are in the table, a set bit 27 is
//!   one flag (one fault), shown as "STATE_LOGIC_VOLT (STATE_POW_SETUP_ERR)" so both names are findable. The five flags the manual lists after STATE_LOGIC_VOLT (POW_WDG_TEMP,
//!   POW_SHORTCUR, POW_HALLERR, CPU_OVERLOAD, POW_SETUP_ERR) are classed obsolete (the manual's colour
//!   legend is lost in the text); STATE_HALTED and STATE_CURLIMIT are information. A client error names
//!   every set flag that is not information.
//! - **Parameter types.** TargetPosInc and StepInc are positions in ticks and are signed (Int32); the
//!   manual prints UInt32. DefA0 has no access mark in the manual: it is read-only like the other defaults.
//!   ActFPosStateDio (0x62) carries 6 bytes (float, short state, DIO) and ActFPosTime (0xA1) 6 (float,
//!   UInt16 ms), so their GetExtended acknowledges are 8 bytes long.
//! - **Profibus short state.** [`wire::profibus::InputImage::short_state`] is the typed
//!   [`model::ProfibusState`] (the method lives in `model`, which gives the bits their meaning; the wire has
//!   `short_state_raw`).
//! - **Profibus byte 7.** Commands of up to 7 bytes get a rolling counter in byte 7. An 8-byte command
//!   (FSTEP, ISTEP, FCOSLOOP) fills byte 7 itself; sent twice in a row the image would not change, so the
//!   writer refuses the repeat rather than letting the module ignore it silently.
//! - **Writes the module cannot apply.** The emulator acknowledges a write of a read-only parameter and
//!   ignores it; unknown commands, parameters and modes get no acknowledge. The same for values it cannot
//!   limit to anything: a NaN or infinite value, a motion to a NaN or infinite target, a soft limit that
//!   would cross the other one (MinPos above MaxPos): acknowledged with 0x64 (the manual defines no other
//!   status for SetExtended) and ignored, so MinPos <= MaxPos always holds. The client refuses such requests
//!   before sending, however they were built: every request goes through [`wire::Request::validate`] (the
//!   rules of [`wire::Request::set`], [`wire::Request::get`], [`wire::Request::motion`]: access, type,
//!   finite floats, a MotionID for the acknowledge asked).
//! - **Config's class.** The manual marks Config "(Vorgabe)", a label no other parameter has and which is
//!   none of its four classes: it is not in ROM (DefConfig is), limits nothing and is no motion target. It
//!   is [`model::ParamClass::Setting`]: written by the host, lost at power off.
//! - **Limits.** Soft limits apply only after homing (chapter 12). Ramp targets beyond them are limited to
//!   them; velocity, current and loop motions that reach them stop with STATE_BEYOND_SOFT, STATE_ERROR and
//!   STATE_HALTED. TargetVel and TargetAcc are limited to MaxVel and MaxAcc when a ramp starts. Motion
//!   commands to a halted module are acknowledged and ignored.
//! - **Emulated physics.** Homing ramps to the home switch at position 0 with DefHomeVel and DefHomeAcc.
//!   Velocity mode accelerates with TargetAcc; current mode moves at `current / MaxCur × MaxVel`. Step mode
//!   moves at constant speed and buffers one more step (a newer one replaces it). FCOSLOOP oscillates on a
//!   cosine between the start and the target with the given period; FRAMPLOOP ramps back and forth (a loop
//!   whose legs would last under 1 ms ends after its first leg). The servo lags 5 ms: the following error
//!   is the velocity × 5 ms, and a tow error is raised when it exceeds MaxDeltaPos.
//! - **Close.** Closing (or dropping) a [`Client`] reads the state of every module it set in motion and halts those
//!   still moving or not answering (with a broadcast halt if single halts fail). A wait that times out or
//!   is cancelled halts its module. Then the session stops serving cleanly: if it switched watchdogs on,
//!   it switches them off and restores the Config words ([`Client::disable_watchdog`]) before it stops
//!   the refresh thread, so a program that ends normally leaves no module to halt 50 ms later. Unless the
//!   session failed ([`Session::failed`]: a link error, a refresh that could not be sent, a module it
//!   started that stopped answering): then the watchdogs stay online and the modules halt within 50 ms,
//!   which is what the watchdog is for. (The `motionlink` command switches it off itself at the end of
//!   `home` and `move`, also after Ctrl-C or an error.)
//! - **Scan.** Silence is absence; a corrupt answer is asked again like any read, and silence then is
//!   absence too (with a warning: on RS232 a frame with a wrong BCC names no trustworthy address); a module
//!   that answers the scan but cannot then be read is listed with its error ([`session::ScanEntry`]) rather
//!   than failing the scan.
//! - **SLCAN refusals.** An adapter that rings the bell for a frame (channel closed, queue full, bus off)
//!   makes the next receive fail with a [`LinkError`](motionlink_link::LinkError) naming the frame: the
//!   request fails at once as a transport error, not after a timeout.
//! - **Timeouts.** RS232 200 ms (a frame takes up to 25 ms each way at 9600 baud), CAN 50 ms; reads are
//!   retried twice; the scan waits 60 ms per address on RS232 and 50 ms for all 31 on CAN. Waits poll every
//!   10 ms on a fixed schedule, never faster. All are [`session::Config`] settings.
//! - **In-position.** The manual has no in-position window parameter: [`client::Module::move_to`] takes the
//!   tolerance from its caller ([`session::MoveSpec::DEFAULT_TOLERANCE`]: 0.001 rad or m) and reads the final
//!   position twice; both readings must lie within it.
//! - **Limits are refused, not clamped.** The modules limit targets to MinPos/MaxPos (once homed), MaxVel,
//!   MaxAcc, MaxCur (chapter 12). [`client::Module::move_to`] and [`client::Module::set_checked`] refuse such
//!   values before anything moves ([`Error::OutsideLimits`]), homed or not, and read back what they
//!   write ([`Error::ReadBack`]); a module's own limits, when written, are read back as well.
//! - **The target of a running motion.** TargetPosInc is taken as the target of the motion the module runs
//!   (the emulator sets it from FRAMP); `move_to` reads it right after the motion command and halts the
//!   module on a difference of more than one tick: the modules ignore the BCC, so a corrupted command would
//!   otherwise run to a wrong place. To be confirmed on real hardware.
//! - **Every motion mode, checked.** Beside the ramp move [`session::Op::MoveTo`] (and
//!   [`session::Op::MoveGuarded`]), [`session::Op::RunMotion`] ([`client::Module::run_motion`],
//!   [`session::MotionSpec`]) runs any of the manual's modes with the same rigour and ends with a
//!   [`session::MotionReport`]. Limits are refused before anything moves: float targets and a loop's far
//!   end against MinPos/MaxPos; tick targets (IRAMP, ISTEP) against the module's own ActIMinPos/ActIMaxPos
//!   and IVEL against ActIMaxVel, in ticks (no IncRatio rounding); FVEL against MaxVel, FCUR against MaxCur,
//!   ICUR within -500..500 digits; a step's distance over its time against MaxVel (a step the module would
//!   have to stretch). The ramps end on STATE_RAMP_END; the steps, which set no ramp end, on STATE_MOTION
//!   clear; both within the tolerance of their target. The target is read back from TargetPosInc (FRAMP,
//!   IRAMP, as `move_to` does) or StepInc (FSTEP, ISTEP; read again after the step when a step under way or
//!   a late start had not shown it yet). The continuous modes (FVEL, IVEL, FCUR, ICUR, FCOSLOOP,
//!   FRAMPLOOP) run for a hold, watched as a wait watches a motion, and are then ended: a velocity mode with
//!   the same mode at velocity 0 and the wait for rest, a current or loop mode with a Halt confirmed by its
//!   state (the module then takes no motion until a reset). What cannot be read back (a velocity's or a
//!   current's value, a loop's far end) is said in the report's `not_verifiable`. For control loops,
//!   [`session::Op::Setpoint`] ([`client::Module::setpoint`]) streams one motion command per cycle
//!   (typically FVEL_ACK, whose acknowledge gives the position, short state and DIO): the same numbers and
//!   limits checked, against limits read at the first call to a module and cached (dropped when this
//!   session writes a limit or the Config word, resets, homes or halts the module, or a setpoint fails; a
//!   limit another program changes is not seen until then), so that each later call is one exchange; a
//!   SHORT_NOT_OK in the acknowledge has the state read (a fault or a halt ends the stream with its error).
//! - **Stops that cannot be confirmed.** When an action that may have set a module in motion cannot go on,
//!   the module is halted: up to three Halts by address (a Halt may be repeated), the state read after an
//!   acknowledged one until STATE_MOTION clears (at most [`session::HALT_SETTLE`]), and, unless it was seen
//!   at rest, a broadcast Halt and the watchdog refresh stopped on purpose ([`Session::abandon_watchdog`]):
//!   an armed module then halts itself within 50 ms. The error carries a [`error::StopOutcome`] whose text
//!   says whether the module confirmed the stop, and if not, that the axis may still be moving.
//! - **Acknowledges nobody asked for.** A module that acknowledges a motion command it was not sent in this
//!   exchange (an address corrupted on the way) is counted as set in motion, so that the session halts it.
//! - **Units.** The manual's floats are in the module's unit (rad rotary, m linear). [`model::Position`] and
//!   its siblings say rad or m, or explicitly [`model::AxisUnit::ModuleUnit`] (a bare command-line number, a
//!   value decoded from the wire); a quantity in rad or m is checked against the module's kind (read once
//!   from its Config word) before anything is sent ([`Error::UnitMismatch`]).
//! - **Operations as `async fn`s.** Each multi-step operation of the [`Session`] is an `async fn` over the
//!   session's state, which the compiler makes a state machine; the one executor of `motionlink-link`
//!   ([`motionlink_link::exec`]) resumes it when what it waits for is there (no thread, no I/O).
//! - **Cancelling.** A read or a scan that is cancelled ends at once ([`Error::CancelledBeforeMotion`]); a motion, a
//!   wait or homing is halted first ([`Error::Cancelled`] says whether that was confirmed); writes and
//!   watchdog changes run to their end.
//! - **Closing is bounded** ([`session::Config::close_bound`], 5 s): past it, [`Error::CloseTimedOut`],
//!   and the refresh stops with the session, so an armed module halts itself within 50 ms.
//! - **DISABLE_ACK.** The client refuses to set CONFIGID_MOD_DISABLE_ACK on CAN (it needs acknowledges).
//!   The emulator honours it; the write that sets it is still acknowledged.

#![warn(missing_docs)]

pub mod args;
pub mod client;
pub mod describe;
pub mod error;
pub mod model;
pub mod probe;
pub mod report;
pub mod session;
pub mod sim;
pub mod wire;

#[cfg(feature = "tokio")]
pub use client::AsyncClient;
pub use client::Client;
pub use client::PortLink;
pub use error::Error;
pub use session::Session;
pub use sim::Emulator;
