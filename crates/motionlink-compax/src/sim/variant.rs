//! Firmware variants of the emulated drives: each models one behaviour the manual leaves open the other
//! plausible way, so that the client is tried against drives that do not behave as our default emulator
//! does (`motionlink sim compax --variant NAME`, `variants = [...]` in the emulator's TOML).
//!
//! The manual says of the echo only that "COMPAX will send the received data back in full". The default
//! emulator reads "in full" as everything before the CR: the address digits, the command and the flag
//! characters (`1POSA 12.5,?`). It sends the `$` message when a positioning asked for one ends (the user
//! guide's word), answers at once (the manual gives no reply time; the client allows 200 ms beyond the wire
//! time), and holds one command in its buffer, which the next store replaces (the manual speaks of "the
//! COMPAX buffer" and says neither how many commands it holds nor whether a store replaces one). The variants:
//!
//! | variant | what the drives do differently |
//! |---|---|
//! | `echo-without-address` | The echo leaves out the address digits the telegram began with (`POSA 12.5,?`). |
//! | `echo-bare` | The echo is the command alone: no address digits, and none of the flag characters `$`, `,`, `/`, `?` at its end (`POSA 12.5`). |
//! | `no-echo` | `?` is not known: a telegram with it is refused (E90, as any syntax the drive cannot read) and nothing is stored. |
//! | `echo-without-store` | `?` sends the telegram back instead of processing it, `,` included: a command sent with `,?` is echoed but not stored (so the `!` after it finds an empty buffer). |
//! | `status-value-only` | A status value is answered with the value alone (`12.500`), not after its name (`S001: 12.500`). |
//! | `no-position-message` | A move sent with `$` runs, but the drive never sends the `$` message when it ends. |
//! | `slow-replies` | Everything the drives send goes out [`SLOW_REPLY_DELAY`] (300 ms) after it would have: beyond the client's default reply timeout of 200 ms. |
//! | `buffer-queues` | The buffer is a queue: each store (`,`) appends a command (up to [`QUEUE_DEPTH`]; beyond, a store is refused with E90 and nothing stored), and `!` executes the oldest. |
//! | `no-command-bit` | S17 bit 3 ("command active", the user guide's, not the RS485 manual's) stays clear while a positioning runs. |
//! | `echo-executes` | A command sent with `?` (without `,`) is carried out as well as echoed (the manual says only that the drive sends it back): `1POSA 10?` moves the axis. |
//!
//! Every reply keeps the framing P196 asks for (its address prefix, its end, its BCC): a variant changes
//! what the drive says, not how it frames it.

use std::time::Duration;

use motionlink_link::emulator::FirmwareVariant;
pub use motionlink_link::emulator::UnknownVariant;

/// How much later than the default drives a drive of the `slow-replies` variant sends everything
/// ([`Variant::SlowReplies`]): 300 ms, beyond the client's default reply timeout of 200 ms.
pub const SLOW_REPLY_DELAY: Duration = Duration::from_millis(300);

/// How many commands the buffer of a drive of the `buffer-queues` variant holds ([`Variant::BufferQueues`]).
pub const QUEUE_DEPTH: usize = 8;

/// One firmware variant of the emulated drives (see the module documentation of `sim::variant`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Deserialize)]
#[serde(try_from = "String")]
pub enum Variant {
    /// The echo without the address digits.
    EchoWithoutAddress,
    /// The echo without the address digits and without the flag characters.
    EchoBare,
    /// No echo: `?` is refused.
    NoEcho,
    /// `,?` echoes without storing.
    EchoWithoutStore,
    /// Status values without their name.
    StatusValueOnly,
    /// No `$` message when a positioning that asked for one ends.
    NoPositionMessage,
    /// Everything the drives send comes [`SLOW_REPLY_DELAY`] late.
    SlowReplies,
    /// The buffer is a queue: each store appends, `!` executes the oldest.
    BufferQueues,
    /// S17 never shows "command active": a positioning runs with the bit clear.
    NoCommandBit,
    /// `?` (without `,`) carries the command out as well as echoing it.
    EchoExecutes,
}

impl FirmwareVariant for Variant {
    const FAMILY: &'static str = "COMPAX";
    /// Every variant, in the order of the table above.
    const ALL: &'static [Variant] = &[
        Variant::EchoWithoutAddress,
        Variant::EchoBare,
        Variant::NoEcho,
        Variant::EchoWithoutStore,
        Variant::StatusValueOnly,
        Variant::NoPositionMessage,
        Variant::SlowReplies,
        Variant::BufferQueues,
        Variant::NoCommandBit,
        Variant::EchoExecutes,
    ];

    /// The name the command line, the TOML configuration and Python take.
    fn name(self) -> &'static str {
        match self {
            Variant::EchoWithoutAddress => "echo-without-address",
            Variant::EchoBare => "echo-bare",
            Variant::NoEcho => "no-echo",
            Variant::EchoWithoutStore => "echo-without-store",
            Variant::StatusValueOnly => "status-value-only",
            Variant::NoPositionMessage => "no-position-message",
            Variant::SlowReplies => "slow-replies",
            Variant::BufferQueues => "buffer-queues",
            Variant::NoCommandBit => "no-command-bit",
            Variant::EchoExecutes => "echo-executes",
        }
    }

    /// What the drives do differently, in one sentence.
    fn description(self) -> &'static str {
        match self {
            Variant::EchoWithoutAddress => "the echo leaves out the address digits",
            Variant::EchoBare => "the echo is the command alone, without the address and the flag characters",
            Variant::NoEcho => "'?' is refused (E90) and nothing is stored",
            Variant::EchoWithoutStore => "a command sent with ',?' is echoed but not stored",
            Variant::StatusValueOnly => "status values come without their name (12.500, not S001: 12.500)",
            Variant::NoPositionMessage => "a move sent with '$' runs, but no '$' message comes when it ends",
            Variant::SlowReplies => {
                "every reply comes 300 ms late (beyond the client's default reply timeout of 200 ms)"
            }
            Variant::BufferQueues => "the buffer is a queue: each store appends a command, '!' executes the oldest",
            Variant::NoCommandBit => "S17 bit 3 (command active) stays clear while a positioning runs",
            Variant::EchoExecutes => "a command sent with '?' (without ',') is carried out as well as echoed",
        }
    }
}

motionlink_link::firmware_variant_traits!(Variant);

/// The echo a drive of `variants` sends for the telegram `received` (everything before its CR) whose
/// address took its first `address_len` bytes.
pub(crate) fn echo_of<'a>(variants: &[Variant], received: &'a [u8], address_len: usize) -> &'a [u8] {
    let without_address = received.get(address_len..).unwrap_or_default();
    if variants.contains(&Variant::EchoBare) {
        let end = without_address.iter().rposition(|c| !b"$,/?".contains(c)).map_or(0, |i| i + 1);
        &without_address[..end]
    } else if variants.contains(&Variant::EchoWithoutAddress) {
        without_address
    } else {
        received
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_unknown_ones_are_refused_with_the_list_and_the_echo_forms() {
        for &v in Variant::ALL {
            assert_eq!(v.name().parse::<Variant>(), Ok(v));
            assert!(v.description().len() > 10 && v.to_string() == v.name(), "{v}");
        }
        assert_eq!(Variant::list("no-echo, echo-bare,no-echo").unwrap(), vec![Variant::EchoBare, Variant::NoEcho]);
        assert_eq!(" No_Echo ".parse::<Variant>(), Ok(Variant::NoEcho));
        let e = "echo".parse::<Variant>().unwrap_err().to_string();
        assert_eq!(
            e,
            "\"echo\" is not a variant of the COMPAX emulator (known: echo-without-address, echo-bare, no-echo, \
             echo-without-store, status-value-only, no-position-message, slow-replies, buffer-queues, no-command-bit, \
             echo-executes)"
        );
        let t = b"12POSA 12.5$,?";
        assert_eq!(echo_of(&[], t, 2), t);
        assert_eq!(echo_of(&[Variant::EchoWithoutAddress], t, 2), b"POSA 12.5$,?");
        assert_eq!(echo_of(&[Variant::EchoBare], t, 2), b"POSA 12.5");
    }
}
