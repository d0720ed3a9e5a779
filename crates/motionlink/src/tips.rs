//! clap's "a similar subcommand exists" and "a similar argument exists" tips, chosen the way every name of
//! motionlink is matched ([`motionlink_link::table::nearest`]: the edit distance, ignoring case, the best
//! one or two within a third of the length): `powercube stpo` suggests `stop` alone (clap's own measure
//! also offers `set`), `powercube STOP` suggests `stop`, `move --vell` suggests `--vel`. A negative number
//! in a form clap splits into short options (`-5e`, `-inf`) is named whole, as a value that is not a number.

use std::ffi::OsString;

use clap::error::{ContextKind, ContextValue, ErrorKind};
use motionlink_link::table::nearest;

/// `error` with its tip chosen by [`nearest`] among the subcommands (or the options) of the command the
/// misspelt word was given to in `args`; without a tip when none is near.
pub fn better_tips(mut error: clap::Error, command: &clap::Command, args: &[OsString]) -> clap::Error {
    let mut command = command.clone();
    command.build();
    match error.kind() {
        ErrorKind::InvalidSubcommand => {
            let Some(ContextValue::String(word)) = error.get(ContextKind::InvalidSubcommand).cloned() else {
                return error;
            };
            let level = level_of(&command, args, &word);
            let names = level.get_subcommands().flat_map(|c| std::iter::once(c.get_name()).chain(c.get_all_aliases()));
            let found: Vec<String> = nearest(&word, names).into_iter().map(str::to_string).collect();
            if found.is_empty() {
                error.remove(ContextKind::SuggestedSubcommand);
            } else {
                error.insert(ContextKind::SuggestedSubcommand, ContextValue::Strings(found));
            }
        }
        ErrorKind::UnknownArgument => {
            let Some(ContextValue::String(word)) = error.get(ContextKind::InvalidArg).cloned() else { return error };
            if let Some(number) = malformed_number(args, &word) {
                let message = format!(
                    "invalid value '{number}': not a number (a negative number is written like -5, -0.5 or -1e-3)"
                );
                return clap::Error::raw(ErrorKind::InvalidValue, format!("{message}\n")).with_cmd(&command);
            }
            let Some(flag) = word.strip_prefix("--") else { return error };
            let flag = flag.split_once('=').map_or(flag, |(f, _)| f);
            let level = level_of(&command, args, &word);
            let longs = level
                .get_arguments()
                .filter(|a| !a.is_hide_set())
                .flat_map(|a| a.get_long().into_iter().chain(a.get_all_aliases().into_iter().flatten()));
            match nearest(flag, longs).first() {
                Some(found) => {
                    error.insert(ContextKind::SuggestedArg, ContextValue::String(format!("--{found}")));
                }
                None => {
                    error.remove(ContextKind::SuggestedArg);
                }
            }
        }
        _ => {}
    }
    error
}

/// The word of `args` (before `--`) that clap split into the unknown short option `flag` (`-5` of `-5e`, `-i`
/// of `-inf`), when that word is a negative number in a form clap does not take for one (`-5e`, `-1_0`,
/// `-.5e`, `-inf`, `-NaN`): no option of motionlink is a dash and a digit, so the user meant a number. A
/// word that is a number (`-5` where no value is taken) keeps clap's "unexpected argument".
fn malformed_number(args: &[OsString], flag: &str) -> Option<String> {
    let is_number_like = |word: &str| {
        word.parse::<f64>().map_or(true, |v| !v.is_finite())
            && word.strip_prefix('-').is_some_and(|rest| {
                rest.starts_with(|c: char| c.is_ascii_digit() || c == '.')
                    || ["inf", "infinity", "nan"].iter().any(|n| rest.eq_ignore_ascii_case(n))
            })
    };
    let words = args.iter().skip(1).map(|a| a.to_string_lossy()).take_while(|a| a != "--");
    words.filter(|w| w.starts_with(flag) && is_number_like(w)).map(|w| w.into_owned()).next()
}

/// The (sub)command that `word` was given to in `args`: the deepest subcommand named before it.
fn level_of<'a>(command: &'a clap::Command, args: &[OsString], word: &str) -> &'a clap::Command {
    let mut level = command;
    for arg in args.iter().skip(1) {
        let arg = arg.to_string_lossy();
        if arg == word || arg.strip_prefix(word).is_some_and(|rest| rest.starts_with('=')) || arg == "--" {
            break;
        }
        if let Some(sub) = level.find_subcommand(arg.as_ref()) {
            level = sub;
        }
    }
    level
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    fn tip(args: &[&str]) -> (ErrorKind, Option<ContextValue>) {
        let args: Vec<OsString> = args.iter().map(OsString::from).collect();
        let command = crate::Cli::command();
        let e = command.clone().try_get_matches_from(&args).unwrap_err();
        let e = better_tips(e, &command, &args);
        let tip = e.get(ContextKind::SuggestedSubcommand).or(e.get(ContextKind::SuggestedArg)).cloned();
        (e.kind(), tip)
    }

    #[test]
    fn a_misspelt_subcommand_or_option_gets_the_nearest_one_only() {
        let stop = tip(&["motionlink", "powercube", "--port", "sim", "stpo"]);
        assert_eq!(stop, (ErrorKind::InvalidSubcommand, Some(ContextValue::Strings(vec!["stop".into()]))));
        let upper = tip(&["motionlink", "powercube", "STOP"]);
        assert_eq!(upper.1, Some(ContextValue::Strings(vec!["stop".into()])));
        let vel = tip(&["motionlink", "powercube", "move", "1", "--vell", "2"]);
        assert_eq!(vel, (ErrorKind::UnknownArgument, Some(ContextValue::String("--vel".into()))));
        let port = tip(&["motionlink", "scu", "--prot", "sim", "info"]);
        assert_eq!(port.1, Some(ContextValue::String("--port".into())), "a global option of the family");
        let none = tip(&["motionlink", "powercube", "banana"]);
        assert_eq!(none.1, None, "nothing near: no tip");
    }

    #[test]
    fn a_negative_number_clap_does_not_take_is_named_whole() {
        let message = |args: &[&str]| {
            let args: Vec<OsString> = args.iter().map(OsString::from).collect();
            let command = crate::Cli::command();
            let e = command.clone().try_get_matches_from(&args).unwrap_err();
            let e = better_tips(e, &command, &args);
            (e.kind(), e.render().to_string())
        };
        for (word, args) in [
            ("-5e", &["motionlink", "powercube", "move", "-5e"][..]),
            ("-5e", &["motionlink", "powercube", "move", "1", "--vel", "-5e"][..]),
            ("-1_0", &["motionlink", "compax", "move", "-1_0"][..]),
            ("-.5e", &["motionlink", "compax", "move", "-.5e"][..]),
            ("-inf", &["motionlink", "scu", "move", "1", "-inf"][..]),
        ] {
            let (kind, text) = message(args);
            assert_eq!(kind, ErrorKind::InvalidValue, "{args:?}: {text}");
            assert!(text.contains(&format!("invalid value '{word}': not a number")), "{args:?}: {text}");
            assert!(!text.contains("unexpected argument"), "{text}");
        }
        // An unknown option that is no number keeps clap's own message, and so does a number where no value
        // is taken.
        let (kind, text) = message(&["motionlink", "powercube", "move", "1", "-x"]);
        assert_eq!(kind, ErrorKind::UnknownArgument, "{text}");
        let (kind, text) = message(&["motionlink", "powercube", "info", "-5"]);
        assert_ne!(kind, ErrorKind::InvalidValue, "{text}");
        assert!(text.contains("unexpected argument '-5'") && !text.contains("not a number"), "{text}");
    }
}
