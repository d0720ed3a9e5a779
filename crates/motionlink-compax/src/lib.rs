//! Parker (EMD Hauser) COMPAX servo drives over the RS485 option F1 / F5 (and RS232): the ASCII and binary
//! protocol, a client for a multi-drop bus of up to 31 drives, and an emulator of such a bus.
//!
//! Layers, bottom to top, each using only those below it:
//! - [`wire`]: the sans-IO codec. Requests `address + command [$][,][/][?] CR [BCC]` and binary telegrams,
//!   replies `[address] text CR LF > [BCC]` (or `CR` alone), P196 as one typed [`wire::Mode`], the 24.24 and
//!   16-bit number formats, incremental decoders that resynchronise after garbage. No allocation on the hot
//!   path.
//! - [`model`]: the vocabulary: [`model::Command`] (POSA, POSR, SPEED, ACCEL, ACCEL-, OUTPUT, POSA HOME and
//!   the short forms), status values S1..S40 ([`model::StatusId`], the shared-table rows [`model::STATUS`],
//!   the S16 / S17 words through the shared `flag_set!`, the S18 history), parameters ([`model::ParamId`],
//!   [`model::PARAMS`]), error codes ([`model::ErrorCode`]), and quantities with their unit
//!   ([`model::Position`] in the drive's unit, [`model::SpeedPercent`], [`model::RampMs`]).
//! - [`session`]: the protocol as a sans-IO [`Session`]: request / reply matching, retries of what may be
//!   retried, every multi-step operation ([`session::Op`]: checked moves, waits, the scan, the synchronous
//!   start, parameter writes read back, the watch) as an `async fn` run by the one executor of
//!   `motionlink-link`, and the stop of whatever it set in
//!   motion when an operation is cancelled or fails and when it is closed; tested with a manual clock and no
//!   link.
//! - [`client`]: [`Client`] (blocking, `&self`, shareable between threads) and, with the `tokio` feature,
//!   `AsyncClient`: the same typed operations over [`motionlink_link::driver`] running the session (for
//!   async callers a drive handle `AsyncDrive` and a watch stream `AsyncWatch`); [`client::Drive`], a handle
//!   on one drive. Closing stops what was started, bounded in time.
//! - [`report`]: what the operations report, serialising (serde) with the names of the command line's
//!   `--json`, which every front end shows.
//! - [`sim`]: [`Emulator`], a sans-IO emulator of the bus with a motion model.
//! - [`describe`]: [`Describe`](motionlink_link::describe::Describe) for captures, the demo and
//!   `motionlink decode compax`.
//! - [`Error`]: one error type, classified ([`Classify`](motionlink_link::error::Classify)).
//!
//! ```
//! use motionlink_compax::client::{Config, MoveOptions};
//! use motionlink_compax::model::{Position, SpeedPercent};
//! use motionlink_compax::sim::SimConfig;
//! use motionlink_compax::wire::{Address, Mode};
//! use motionlink_compax::{Client, Emulator};
//! use motionlink_link::{clock::{Clock, ManualClock}, pipe::{EmulatorHost, PipeConfig}};
//!
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let sim = Emulator::new(SimConfig::bus(&[1, 5], 8, 9600)).unwrap(); // P196 = 8: with BCC
//! let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(9600));
//! let bus = Client::with_link(Box::new(host.connect().0), clock.shared(),
//!                       Config::new(Mode::from_p196(8).unwrap(), 9600)).unwrap();
//! let one = Address::drive(1).unwrap();
//! bus.set_speed(one, SpeedPercent::new(50.0).unwrap(), false).unwrap();
//! bus.move_relative(one, Position::new(10.0).unwrap(), MoveOptions { binary: true, message: false }).unwrap();
//! bus.wait_reached(&[one], None, &mut |_, p| println!("at {p}")).unwrap();
//! assert_eq!(bus.read_position(one).unwrap().units(), 10.0);
//! ```
//!
//! # Decisions
//!
//! No public software speaks this protocol; the RS485 option manual (V1.20, 1997) and the COMPAX-M / -S user
//! guide are the sources. Where they are silent or contradict themselves:
//!
//! - **BCC** is the XOR of every character before the CR, the address included (the manual's BASIC routine
//!   computes it so for both directions). In a reply it comes after the prompt `>` (or after the CR when
//!   P196 has 32). A binary telegram has no CR: its BCC covers the address digits and every command byte.
//! - **P196** accepts 0..=127: the table prints 31 as the maximum, but its valences include 32 and 64.
//!   164 / 165 (the COMTAC fieldbus protocol) are refused. Valence 4 (even) without 2 (parity on) means no
//!   parity. P194..P196 are "valid from power-on": a written value is stored and read back at once, and takes
//!   effect when the drive is switched off and on ([`Emulator::power_cycle`]).
//! - **Reply texts**: a status value is answered `S001: 360.000` (the user guide's S18 example has the form
//!   `S018: 99 55 10 ...`; positions with three decimals, the drives' 0.001 resolution), S16 / S17 as eight
//!   bits, bit 1 first (`S017: 1000 0000`, as the user guide writes it), a parameter `P194=5` (the form of a
//!   write), a command without answer the empty text (`CR LF >` alone). The client accepts the value with or
//!   without the name in front, so either form of a real drive reads.
//! - **`$`** (position reached) is the user guide's `$ CR LF >`, with the address prefix and BCC of P196.
//!   The emulator holds it while a telegram is being received and sends it after the reply. Without the
//!   address prefix a `$` cannot name its drive: the client attributes it only when one drive awaits one,
//!   and otherwise polls S17. A `$` can be lost (a line error), and none comes for a positioning that
//!   someone else ends, so a wait for `$` also reads S17 once a second; a wait has a default limit of 600 s.
//! - **`!`** executes the command in the buffer and answers as that command would (empty for a move, the
//!   value for a read). The buffer holds one command (user guide) and is emptied by `!`, so a repeated
//!   `32!` cannot move an axis twice; `!` with an empty buffer is refused.
//! - **`?`** (echo) sends the telegram back (address, command and flags, without CR) and does not execute
//!   it. The echo ends as P196 says, like every reply (the manual writes `CR LF >`, which would break a bus in
//!   CR-only mode). With `,` (`POSA 10,?`) the command is stored as with `,` alone and echoed: the manual
//!   lists the two among the optional characters of one telegram and excludes neither.
//! - **Binary replies** are the ASCII ones (`CR LF >` or `Exx`); binary commands take no flags. The binary
//!   table's last row prints five bytes for the speed; the length byte 0x8F says six, as everywhere else.
//!   "POSA 256,0 → 88 41 00 00 00 01 00" misses a byte (`88 41 00 00 00 00 01 00`); the number table's
//!   "400,5" is 450.5 (0x1C2 = 450, the worked example's number). The 16-bit format is two's complement;
//!   ramp times are 0..=32767 ms.
//! - **Stop**: `OUTPUT O0=0` ("switch off drive", user guide). The command set has no stop that works while a
//!   positioning runs: every move command is refused with E92 then. The client sends it addressed to each
//!   drive it started (a broadcast would also stop drives that other programs run) and only if the drive
//!   still moves: the session's stop (used on drop, on a cancelled or failed wait) reads S17 first
//!   and sends the stop when "command active" is set, and also when S17 cannot be read (a line failure: the
//!   stop is sent anyway, so an axis is never left running because its state was unreadable), then reads
//!   S17 again to confirm the axis is at rest (sending the stop once more if not): the
//!   [`error::StopReport`] says per drive whether the drive confirmed it, and if not, that the axis may
//!   still be moving. [`Client::stop`] switches the drive off unconditionally. `OUTPUT O0=1` switches
//!   the drive on again; the emulator powers up switched on, and refuses moves while switched off.
//! - **No host watchdog**: the manual has none, so a host that dies leaves a positioning running. P196's
//!   timeout supervision (valence 16) is an inter-character timeout inside one telegram (E73), not a
//!   watchdog.
//! - **Checked moves** ([`Client::move_to`]): the manuals give no position window for this protocol,
//!   so the in-position tolerance is
//!   [`Config::in_position_tolerance`](session::Config::in_position_tolerance) (0.01 by default); they
//!   name no travel limits, so the caller gives them ([`session::TravelLimits`]). The move is checked
//!   before it starts: it is stored in the drive's buffer with its echo (`POSA 12.5,?`), the echo is
//!   compared byte for byte with the telegram sent (address prefix, address, command, value, flags), and
//!   only when they are the same is `!` sent. How much of the telegram a drive echoes ("in full" is all the
//!   manual says) is found out per drive with S1 sent with `?` and remembered ([`session::EchoForm`]); the
//!   echo is compared in that form, the command text always exactly; a drive that echoes less, or not at
//!   all, has its moves reported as not verified in what they could not check
//!   ([`session::MoveReport::not_verifiable`]). The emulator's firmware variants ([`sim::Variant`]) model
//!   those other readings. An echo that differs or comes corrupt (a flipped digit, a
//!   flipped address digit that reached another drive) sends no `!` and is [`Error::NotExecuted`], which
//!   names what came back and the drives that may now hold the command in their buffer (the manual has no
//!   command that empties one: the next `!` to such a drive, or any `32!`, executes it). A store whose echo
//!   is lost is stored again for a POSA only: the RS485 manual does not say how many commands the buffer
//!   holds, nor that a store replaces one, and were it a queue a second POSR would run the distance twice
//!   (a second POSA goes to the same target); a POSR whose echo is lost ends in [`Error::NotExecuted`],
//!   naming the drive that may hold it. `!` is never repeated blind: after a lost reply to it,
//!   S2 and S17 tell whether the move started, and `!` goes again only when S2 is unchanged and no command
//!   is active. After the start S2 is read back as a second check, and a mismatch switches the axis off.
//!   A binary move takes no `,` or `?` (manual 4.4): it is checked by S2 after the start only. The drive
//!   counts as started from the first setting of the move on (in binary without BCC one flipped bit turns
//!   SPEED into POSR).
//! - **Replies that cannot answer the request** (text to a move, an acknowledgement or another value to a
//!   read) are taken for late or garbled ones and not used; a read whose reply does not parse is sent again.
//! - **Lost replies**: reads, settings, POSA and buffered POSA are sent again after a timeout or a corrupt
//!   reply (a checked move's store with its echo only after a timeout: a corrupt echo refuses the move). A
//!   POSR stored for a synchronous start is not (were the buffer a queue, it would run twice): the start
//!   ends in [`Error::SyncIncomplete`]. A POSR sent on its own is not either: the client read the target S2 before sending it and reads it again; unchanged, the
//!   move did not arrive and is sent again; moved by the distance, it arrived; otherwise the caller gets
//!   [`Error::MoveUncertain`]. E70, E72 and E73 are always answered by sending the telegram again;
//!   E71 (buffer overflow) is reported, since the manual asks for fewer characters, not the same again.
//! - **Timeouts**: the manual gives none. A reply may take the wire time of request and a 48-character reply
//!   plus 200 ms ([`Config::reply_timeout`](session::Config::reply_timeout)); after a broadcast the
//!   client keeps the line quiet for 20 ms. A telegram unanswered in that time keeps the line quiet for as
//!   long again before anything else is sent (its resend, the next telegram): a reply that comes then is
//!   its own, late, and is dropped rather than taken for the next telegram's (replies name no telegram:
//!   without P196's address prefix a late S1 of drive 1 would read as drive 2's). The timeout then names
//!   how late the replies came ([`Error::Timeout`]`::late`), and a scan warns of an address that answered
//!   too late. Not for the stop's telegrams (a stop does not wait; S17 confirms it), those of a cancelled
//!   operation, nor for the further sendings of a telegram whose late window stayed silent (the line lost
//!   the reply; the drive is not slow).
//! - **Threads**: COMPAX has no watchdog or keepalive. The blocking client drives the line from the calling
//!   thread; the shared driver's one thread (every client starts one) drives it for the async client's
//!   operations, and otherwise only while the session has work and no caller drives the line (as during a
//!   close); between calls it sleeps.
//! - **Broadcast (32)**: nobody answers it, so the client refuses it for reads, echoes, single-drive moves
//!   and waits ([`Error::Broadcast`]) instead of waiting for a reply that cannot come. A move sent to
//!   every drive ([`Client::broadcast`], or `32...` through [`Client::raw`]) counts as started for
//!   each drive that has answered the client: the others it does not know of, and cannot stop.
//! - **Addresses of more than two digits** address no drive: the request decoder keeps two digits and counts
//!   the rest, and such a telegram parses as [`wire::request::RequestError::AddressTooLong`]. It ends at its
//!   CR like any telegram (a drive cannot tell where a run of digits stops either). The BCC a drive checks
//!   is over every character it received, kept or not, so a long telegram with a good BCC is E71, not E72.
//! - **Codes the manuals do not give**: the emulator answers a syntax error, a value out of range, an empty
//!   buffer or a move while switched off with E90 ([`sim::REFUSED`]); a real drive's codes for these are not
//!   in our sources, and the client shows any code with "meaning not documented".
//! - **Status values known**: S1 actual, S2 target, S3 contour error, S6 temperature, S7 / S8 voltages, S9
//!   motion cycles, S10 operating hours, S11 loop counter, S12 absolute sensor, S16 / S17 bits, S18 history,
//!   S30 error, S31..S39 identification (from the user guide and the fieldbus interface description). The
//!   others read as text.
//! - **Motion model** (emulator): SPEED is percent of a maximum speed (100 units/s by default), ACCEL the
//!   time from standstill to that maximum speed, ACCEL- the braking time alone; preparatory commands
//!   (SPEED, ACCEL, comparators `POSR x OUTPUT Oy=z`, speed steps `POSR x SPEED y`) apply to the next
//!   positioning. A comparator sends its number (`1 CR LF >`) when it switches, as in the user guide.
//! - **Bare numbers**: a comparator's message (`1 CR LF >`) looks like a read answered with the bare value
//!   (`35 CR LF >`). A reply to an outstanding request is that request's reply first: while a request
//!   awaits its reply, a bare number is taken as the reply if the request can be answered with it (a status
//!   or parameter read whose value it reads as, an echo, `!`, text the model cannot read), and as a
//!   comparator message otherwise (moves, settings, outputs, S16 / S17 / S18) or when no request awaits one.
//! - **`OUTPUT Ayy`**: the binary table (4.4.1) writes outputs as `Ayy` while its code byte is `4F` (`O`) and
//!   the user guide writes `O9=1`: both spellings are read, `O` is written.
//! - **Synchronous start**: the manual has no command that empties a drive's buffer. If
//!   [`Client::sync_start`] fails to store one move, it sends no `!` and returns
//!   [`Error::SyncIncomplete`] naming the drives that still hold a buffered move (the next `!` to
//!   them, or any `32!`, starts it); a `!` the client sends later counts them as started. A later
//!   synchronous start whose `32!` would run such a move of a drive outside its list is refused before
//!   anything is sent ([`Error::BufferHeld`]).
//! - **Emulator parameters and status values**: the manual defines P194..P196 and no error code for an
//!   invalid parameter or status number (it lists E70..E74 only), so the emulator answers a read or write
//!   of a parameter it does not model ([`sim::SimConfig::params`] adds some) and a status value it does not
//!   model with E90 ([`sim::REFUSED`]), never with a made-up 0. P003, which the user guide writes in its
//!   example, is modelled. S18 records every error a drive meets.

#![warn(missing_docs)]

pub mod client;
pub mod describe;
pub mod error;
pub mod model;
mod options;
pub mod probe;
pub mod report;
pub mod session;
pub mod sim;
pub mod wire;

#[cfg(feature = "tokio")]
pub use client::AsyncClient;
pub use client::Client;
pub use error::Error;
pub use options::{DriveOptions, OptionError};
pub use session::Session;
pub use sim::Emulator;
