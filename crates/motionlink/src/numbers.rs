//! Numbers on the command line: the value parsers of every numeric option and argument, whose messages say
//! what the number is and what it must be. clap names the option and the value it refused (`invalid value
//! '-5' for '--vel <VEL>': the velocity must be a number above 0 (rad/s or m/s)`), and the command exits 2
//! before anything is opened. Negative numbers reach these parsers (main lets every option and argument that
//! takes a value take one), so `--vel -5` is refused for being below 0, not taken for an unknown option.

/// What a whole-number option must be: "a whole number from 1 to 60000 ms", "a whole number, at least 1".
fn whole_range(min: i128, max: Option<i128>, unit: &str) -> String {
    let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
    match max {
        Some(max) => format!("a whole number from {min} to {max}{unit}"),
        None => format!("a whole number{unit}, at least {min}"),
    }
}

/// A whole number `min..=max` (in `unit`, "" for none) for an option whose number is `what` ("the reply
/// timeout"); refused otherwise with "`what` must be a whole number from `min` to `max` `unit`".
pub fn whole<T>(
    what: &'static str,
    min: T,
    max: T,
    unit: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
where
    T: Copy + Into<i128> + TryFrom<i128> + Send + Sync + 'static,
{
    let (lo, hi) = (min.into(), max.into());
    move |text: &str| {
        let refused = || format!("{what} must be {}", whole_range(lo, Some(hi), unit));
        let n: i128 = text.trim().parse().map_err(|_| refused())?;
        if !(lo..=hi).contains(&n) {
            return Err(refused());
        }
        T::try_from(n).map_err(|_| refused())
    }
}

/// A whole number of at least `min` (no upper bound but the type's) for an option whose number is `what`.
pub fn at_least<T>(what: &'static str, min: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
where
    T: Copy + Into<i128> + TryFrom<i128> + Send + Sync + 'static,
{
    let lo = min.into();
    move |text: &str| {
        let refused = || format!("{what} must be {}", whole_range(lo, None, ""));
        let digits = text.trim().strip_prefix('+').unwrap_or(text.trim());
        let n: i128 = match digits.parse() {
            Ok(n) => n,
            // All digits, too many for any type: too large, not "no whole number".
            Err(_) if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) => i128::MAX,
            Err(_) => return Err(refused()),
        };
        if n < lo {
            return Err(refused());
        }
        // A whole number the type cannot hold: its largest said, not the rule it met.
        T::try_from(n).map_err(|_| {
            let widths =
                [u64::MAX.into(), i64::MAX.into(), u32::MAX.into(), i32::MAX.into(), u16::MAX.into(), u8::MAX.into()];
            let most = widths.into_iter().find(|m: &i128| T::try_from(*m).is_ok());
            let most = most.map_or_else(String::new, |m| format!(" (at most {m})"));
            format!("{what} {} is too large{most}", text.trim())
        })
    }
}

/// A finite number (`-1.5`, `2e3`), for a position or a value of `what`, in `unit` ("" for none).
pub fn finite<T: Float>(
    what: &'static str,
    unit: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |text: &str| {
        let unit = if unit.is_empty() { String::new() } else { format!(" ({unit})") };
        T::parse_finite(text).ok_or_else(|| format!("{what} must be a number{unit}"))
    }
}

/// `f32` or `f64`, as [`finite`] parses them.
pub trait Float: Copy + Send + Sync + 'static {
    /// The number `text` says, if it is one and finite (in this type).
    fn parse_finite(text: &str) -> Option<Self>;
}

impl Float for f64 {
    fn parse_finite(text: &str) -> Option<f64> {
        text.trim().parse::<f64>().ok().filter(|v| v.is_finite())
    }
}

impl Float for f32 {
    fn parse_finite(text: &str) -> Option<f32> {
        text.trim().parse::<f32>().ok().filter(|v| v.is_finite())
    }
}

/// Lets every option and argument of `command` (and of its subcommands) that takes a value take a negative
/// number as its value: `--vel -5` then reaches the option's parser, which says why -5 is refused, instead
/// of clap's "unexpected argument '-5'". Flags are left alone.
pub fn negative_values(command: clap::Command) -> clap::Command {
    command
        .mut_args(|a| if a.get_action().takes_values() { a.allow_negative_numbers(true) } else { a })
        .mut_subcommands(negative_values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_numbers_say_what_they_must_be() {
        let ms = whole::<u64>("the reply timeout", 1, 60_000, "ms");
        assert_eq!(ms("200"), Ok(200));
        for bad in ["-5", "0", "60001", "abc", "1.5", ""] {
            assert_eq!(ms(bad), Err("the reply timeout must be a whole number from 1 to 60000 ms".into()), "{bad}");
        }
        let count = at_least::<u64>("the number of samples", 1);
        assert_eq!(count("3"), Ok(3));
        assert_eq!(
            count("99999999999999999999999"),
            Err("the number of samples 99999999999999999999999 is too large (at most 18446744073709551615)".into())
        );
        assert!(at_least::<u32>("n", 1)("4294967296").unwrap_err().ends_with("(at most 4294967295)"));
        let long = "9".repeat(50);
        assert!(count(&long).unwrap_err().contains("is too large (at most 18446744073709551615)"));
        assert_eq!(count("0"), Err("the number of samples must be a whole number, at least 1".into()));
        assert!(count("-1").is_err() && count("many").is_err());
        assert!(whole::<u8>("x", 0, 255, "")("256").is_err());
    }

    #[test]
    fn finite_numbers_refuse_what_is_no_number() {
        assert_eq!(finite::<f32>("the target", "")("NaN"), Err("the target must be a number".into()));
        assert_eq!(finite::<f64>("the target", "")("-1.5"), Ok(-1.5));
        assert_eq!(
            finite::<f64>("the target", "drive units")("x"),
            Err("the target must be a number (drive units)".into())
        );
    }
}
