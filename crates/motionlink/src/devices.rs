//! The options a named device of the configuration file gives a family command or console (`--device
//! lift`; the file and the port are [`motionlink_link::devices`]'s): every key of the device's entry is an
//! option of the family's commands (`motionlink scu ...`) or of its console (`motionlink console scu`), as
//! clap declares them, so a new option is a new key without a list to edit. Each command takes the keys it
//! has an option for; an option given on the command line wins over the file.

use std::ffi::OsString;
use std::path::PathBuf;

use clap::error::ErrorKind;
use clap::parser::ValueSource;

use motionlink_link::devices::{load_with, shown, Device, FAMILIES};
use motionlink_link::table;

use crate::common::{classified, CliError};

/// Options no device entry gives: the one that names the entry; the console's serving address and its
/// opt-in to serve beyond this machine; a move's target (`--abs`, `--rel`: a device has no standing target),
/// the hand-over of a move nothing watches (`--no-wait`), a raw command to every drive (`--broadcast`) and
/// a PowerCube motion's time, hold and tolerance (`--time-ms`, `--for-s`, `motion --tolerance`: a device's
/// `tolerance` is `move`'s, which a velocity would refuse): each must be said on the command line; and clap's
/// own.
const NOT_FROM_THE_FILE: [&str; 15] = [
    "device",
    "listen",
    "listen_any",
    "abs",
    "rel",
    "no_wait",
    "broadcast",
    "time_ms",
    "for_s",
    "motion_tolerance",
    "help",
    "version",
    "verbose",
    "quiet",
    "json",
];

/// `cli` with the options of the device `--device` names in `args` as its defaults, where a family command
/// (`motionlink scu ...`) or a console (`motionlink console scu ...`) names one: each key of the device's
/// entry for which the command (or its action: `move`'s `--max-pos`) has an option, unless the command line
/// gives that option itself or one that excludes it (`--no-wait` and `timeout_s`). The command line is
/// parsed as it is, by the command this returns: what it gives wins over the file. A key that no command of
/// the family has is refused, named, with the nearest one; a value the option refuses is refused as the
/// file's. A command line that clap refuses, or that names no device, leaves `cli` as it is (clap then says
/// what is wrong).
pub fn with_device_options(args: &[OsString], cli: clap::Command) -> Result<clap::Command, CliError> {
    with_device_options_from(args, cli, motionlink_link::profile::devices_path(), |p| std::fs::read_to_string(p))
}

fn with_device_options_from(
    args: &[OsString],
    cli: clap::Command,
    path: Option<PathBuf>,
    read: impl Fn(&PathBuf) -> std::io::Result<String>,
) -> Result<clap::Command, CliError> {
    let taken = match device_defaults(args, &cli, path, read) {
        // Help is shown whatever the device's entry holds (running the command says what is wrong in it).
        Err(_) if args.iter().any(|a| a == "--help" || a == "-h") => return Ok(cli),
        other => other?,
    };
    Ok(taken.into_iter().fold(cli, |cli, (path, id, values)| with_default(cli, &path, &id, values)))
}

/// The default values the device gives: the words that name the option's command (`["scu", "move"]`), the
/// option's id and its values.
type Defaults = Vec<(Vec<String>, String, Vec<String>)>;

fn device_defaults(
    args: &[OsString],
    cli: &clap::Command,
    path: Option<PathBuf>,
    read: impl Fn(&PathBuf) -> std::io::Result<String>,
) -> Result<Defaults, CliError> {
    // With `--help`, the device is found on the command line without it (which may lack what an action
    // requires), so that the help shows the device's values as the defaults; its values are checked when
    // the command runs.
    let without_help: Vec<OsString>;
    let (args, parser, matches) = match cli.clone().try_get_matches_from(args) {
        Ok(matches) => (args, cli.clone(), matches),
        Err(e) if e.kind() == ErrorKind::DisplayHelp => {
            without_help = args.iter().filter(|a| *a != "--help" && *a != "-h").cloned().collect();
            let parser = cli.clone().ignore_errors(true);
            let Ok(matches) = parser.clone().try_get_matches_from(&without_help) else { return Ok(Vec::new()) };
            (&without_help[..], parser, matches)
        }
        Err(_) => return Ok(Vec::new()),
    };
    let Some(levels) = levels(cli, &matches) else { return Ok(Vec::new()) };
    let Ok(Some(name)) = levels[0].matches.try_get_one::<String>("device") else { return Ok(Vec::new()) };
    let family = levels[0].family;
    let (device, shown) = load_with(family, name, path, read).map_err(|e| classified(&e))?;
    let place = format!("{shown}: [device.{name}]");
    check_keys(cli, family, &device, &place)?;
    let port = ("port".to_string(), toml::Value::from(device.port.clone()));
    // What the file adds is checked on a command line with its options written out, one after the other, so
    // that its mistakes are told as the file's; an option that this use of the action cannot take (one it
    // requires is not given) is left out.
    let mut checked = args.to_vec();
    let mut taken = Vec::new();
    for (key, value) in device.options.iter().chain(std::iter::once((&port.0, &port.1))) {
        // The action's option if it has one (`move --tolerance`), else the family's (`--module`).
        let found = levels.iter().enumerate().rev().find_map(|(depth, level)| {
            level.command.get_arguments().find(|a| a.get_id() == key.as_str() && !a.is_positional()).map(|a| (depth, a))
        });
        let Some((depth, arg)) = found else { continue };
        let level = &levels[depth];
        let given = |id: &str| level.matches.value_source(id) == Some(ValueSource::CommandLine);
        if given(key) || level.command.get_arg_conflicts_with(arg).iter().any(|a| given(a.get_id().as_str())) {
            continue;
        }
        let Some(values) = option_values(arg, key, value).map_err(|e| CliError::usage(format!("{place}: {e}")))? else {
            continue;
        };
        let long = arg.get_long().unwrap_or(key);
        let words: Vec<OsString> = match arg.get_action().takes_values() {
            true => values.iter().map(|v| format!("--{long}={v}").into()).collect(),
            false => vec![format!("--{long}").into()],
        };
        let at = insertion_point(cli, &checked, &levels[..=depth]);
        let mut candidate = checked.clone();
        candidate.splice(at..at, words);
        match parser.clone().try_get_matches_from(&candidate) {
            Ok(_) => {
                checked = candidate;
                let words = levels[..=depth].iter().flat_map(|l| l.words.iter().map(|w| w.to_string())).collect();
                taken.push((words, key.clone(), values));
            }
            Err(e) if matches!(e.kind(), ErrorKind::MissingRequiredArgument | ErrorKind::ArgumentConflict) => {}
            Err(e) => {
                let text = e.render().to_string();
                let first = text.lines().next().unwrap_or_default().trim_start_matches("error: ");
                return Err(CliError::usage(format!("{place}: {first}")));
            }
        }
    }
    Ok(taken)
}

/// `cli` with `values` the default of option `id` of the command `path` names below it.
fn with_default(cli: clap::Command, path: &[String], id: &str, values: Vec<String>) -> clap::Command {
    match path.split_first() {
        Some((name, rest)) => cli.mut_subcommand(name, |c| with_default(c, rest, id, values)),
        None => cli.mut_arg(id, |a| a.default_values(values.into_iter().map(clap::builder::OsStr::from))),
    }
}

/// One level of a family's command line: the family command (`scu`, `console scu`) and then its action
/// (`move`), each with its name, clap command and matches.
struct Level<'a> {
    family: &'a str,
    /// The words that name this level, in order (`["console", "scu"]`, `["move"]`).
    words: Vec<&'a str>,
    command: &'a clap::Command,
    matches: &'a clap::ArgMatches,
}

/// The levels of a command line that runs a family command or a console; `None` for any other command.
fn levels<'a>(cli: &'a clap::Command, matches: &'a clap::ArgMatches) -> Option<Vec<Level<'a>>> {
    let (top, sub) = matches.subcommand()?;
    let (family, words, command, matches) = if top == "console" {
        let (family, m) = sub.subcommand()?;
        let family = FAMILIES.iter().find(|f| **f == family)?;
        (*family, vec!["console", *family], cli.find_subcommand("console")?.find_subcommand(family)?, m)
    } else {
        let family = FAMILIES.iter().find(|f| **f == top)?;
        (*family, vec![*family], cli.find_subcommand(top)?, sub)
    };
    let mut levels = vec![Level { family, words, command, matches }];
    if let Some((action, m)) = matches.subcommand() {
        let command = command.find_subcommand(action)?;
        levels.push(Level { family, words: vec![command.get_name()], command, matches: m });
    }
    Some(levels)
}

/// The keys a device of `family` may have: the options of `motionlink <family>`, of its actions, and of
/// `motionlink console <family>`, but [`NOT_FROM_THE_FILE`].
pub(crate) fn family_keys(cli: &clap::Command, family: &str) -> Vec<String> {
    let commands =
        [cli.find_subcommand(family), cli.find_subcommand("console").and_then(|c| c.find_subcommand(family))];
    let mut keys: Vec<String> = commands
        .into_iter()
        .flatten()
        .flat_map(|c| std::iter::once(c).chain(c.get_subcommands()))
        .flat_map(|c| c.get_arguments())
        .filter(|a| !a.is_positional())
        .map(|a| a.get_id().to_string())
        .filter(|id| !NOT_FROM_THE_FILE.contains(&id.as_str()))
        .collect();
    keys.sort();
    keys.dedup();
    keys
}

/// Refuses a key no command of the family has, naming the nearest one and every one there is.
fn check_keys(cli: &clap::Command, family: &str, device: &Device, place: &str) -> Result<(), CliError> {
    let keys = family_keys(cli, family);
    for key in device.options.keys() {
        if keys.contains(key) {
            continue;
        }
        // The nearest keys, if near, by the rule of every "did you mean" of motionlink.
        let near = table::nearest(key, keys.iter().map(String::as_str));
        let hint = table::did_you_mean(&near).map(|d| format!(" ({d})")).unwrap_or_default();
        let why = if NOT_FROM_THE_FILE.contains(&key.as_str()) { " (give it on the command line)" } else { "" };
        return Err(CliError::usage(format!(
            "{place}: unknown key `{key}`{why}{hint}; the {family} options are: {}",
            keys.join(", ")
        )));
    }
    Ok(())
}

/// The values that give option `arg` the file's `value`: one per element of an array for an option that may
/// be repeated, `true` for a switch that is on; `None` for a switch that is off.
fn option_values(arg: &clap::Arg, key: &str, value: &toml::Value) -> Result<Option<Vec<String>>, String> {
    if arg.get_long().is_none() {
        return Err(format!("`{key}` has no long option"));
    }
    if !arg.get_action().takes_values() {
        return match (arg.get_action(), value) {
            (clap::ArgAction::SetTrue, toml::Value::Boolean(true)) => Ok(Some(vec!["true".into()])),
            (clap::ArgAction::SetTrue, toml::Value::Boolean(false)) => Ok(None),
            (clap::ArgAction::SetTrue, other) => {
                Err(format!("`{key}` is a switch: give true or false, not {}", shown(other)))
            }
            _ => Err(format!("`{key}` cannot come from the file (give it on the command line)")),
        };
    }
    let scalar = |v: &toml::Value| match v {
        toml::Value::String(s) => Ok(s.clone()),
        toml::Value::Integer(i) => Ok(i.to_string()),
        // With its decimal point (`50.0`, not `50`): an option of whole numbers refuses it, as on the command line.
        toml::Value::Float(f) => Ok(format!("{f:?}")),
        other => Err(format!("`{key}` = {}: give a string or a number", shown(other))),
    };
    match value {
        toml::Value::Array(items) if matches!(arg.get_action(), clap::ArgAction::Append) => {
            items.iter().map(scalar).collect::<Result<_, _>>().map(Some)
        }
        toml::Value::Array(_) => Err(format!("`{key}` takes one value, not a list")),
        v => Ok(Some(vec![scalar(v)?])),
    }
}

/// Where options of the last of `levels` go in `args`: right after the words that name it (`scu`, `console
/// scu`, then `move`), before the words that follow. The values of options that take one (`--color never`,
/// `--device move`) are no names.
fn insertion_point(cli: &clap::Command, args: &[OsString], levels: &[Level<'_>]) -> usize {
    let commands: Vec<&clap::Command> = std::iter::once(cli).chain(levels.iter().map(|l| l.command)).collect();
    let takes_value = |word: &str| {
        commands.iter().flat_map(|c| c.get_arguments()).any(|a| {
            a.get_action().takes_values()
                && (a.get_long().is_some_and(|l| word == format!("--{l}"))
                    || a.get_short().is_some_and(|s| word == format!("-{s}")))
        })
    };
    let mut wanted = levels.iter().flat_map(|l| l.words.iter().copied());
    let mut next = wanted.next();
    let mut skip = false;
    for (i, word) in args.iter().enumerate().skip(1) {
        let word = word.to_string_lossy();
        if std::mem::take(&mut skip) {
            continue;
        }
        if takes_value(&word) {
            skip = true;
        } else if Some(word.as_ref()) == next {
            next = wanted.next();
            if next.is_none() {
                return i + 1;
            }
        }
    }
    args.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line `words` parsed with the options of `file`'s device as defaults: each option's values
    /// (`None` where it has none), with ` (default)` after those the command line does not give (the file's,
    /// or the option's own default), at the level
    /// `path` names.
    fn parsed(words: &str, file: &str, path: &[&str], ids: &[&str]) -> Result<Vec<Option<String>>, CliError> {
        let args: Vec<OsString> = std::iter::once("motionlink").chain(words.split(' ')).map(OsString::from).collect();
        let cli = crate::numbers::negative_values(<crate::Cli as clap::CommandFactory>::command());
        let cli = with_device_options_from(&args, cli, Some(PathBuf::from("d.toml")), |_| Ok(file.to_string()))?;
        let matches = cli.try_get_matches_from(&args).map_err(|e| CliError::usage(e.to_string()))?;
        let level = path.iter().fold(&matches, |m, name| m.subcommand_matches(name).expect("the level"));
        Ok(ids
            .iter()
            .map(|id| {
                let values = level.get_raw(id)?.map(|v| v.to_string_lossy().into_owned()).collect::<Vec<_>>();
                let given = level.value_source(id) == Some(ValueSource::CommandLine);
                Some(format!("{}{}", values.join(","), if given { "" } else { " (default)" }))
            })
            .collect())
    }

    #[test]
    fn a_devices_options_are_the_defaults_of_their_command() {
        let file = "[device.move]\nfamily = \"compax\"\nport = \"sim\"\ndrive = 3\nmax_pos = 50\ntimeout_s = 9\n\
                    sim_variants = [\"echo-bare\", \"no-echo\"]\nshort = true\n";
        let some = |s: &str| Some(s.to_string());
        // The family's options at `compax`, the action's at `move` (not taken for the device named move).
        let words = "--color never compax --device move move --abs 5";
        assert_eq!(
            parsed(words, file, &["compax"], &["port", "drive", "sim_variants", "short"]).unwrap(),
            [some("sim (default)"), some("3 (default)"), some("echo-bare,no-echo (default)"), some("true (default)")]
        );
        // The key is the option's name (`--sim-variant`: sim_variant) as well as its id (the file's reader
        // takes one for the other).
        let by_name = file.replace("sim_variants", "sim_variant");
        assert_eq!(
            parsed(words, &by_name, &["compax"], &["sim_variants"]).unwrap(),
            [some("echo-bare,no-echo (default)")]
        );
        assert_eq!(
            parsed(words, file, &["compax", "move"], &["timeout_s", "max_pos", "abs"]).unwrap(),
            [some("9 (default)"), some("50 (default)"), some("5")]
        );
        // Given on the command line, or excluded by what is: the command line's.
        let words = "compax --device move move --abs 5 --no-wait --drive 1 --max-pos 60";
        assert_eq!(parsed(words, file, &["compax"], &["drive"]).unwrap(), [some("1")]);
        assert_eq!(
            parsed(words, file, &["compax", "move"], &["timeout_s", "max_pos"]).unwrap(),
            [some("600 (default)"), some("60")]
        );
        // The console: its own options and the family's line options (max_pos, short), not the command's
        // one drive.
        assert_eq!(
            parsed("console compax --device move", file, &["console", "compax"], &["port", "max_pos", "short"])
                .unwrap(),
            [some("sim (default)"), some("50 (default)"), some("true (default)")]
        );
        // A float keeps its decimal point: a whole-number option refuses `9.0` from the file as from the
        // command line (it was taken as 9).
        let words = "compax --device move move --abs 5";
        let float = file.replace("timeout_s = 9", "timeout_s = 9.5");
        assert_eq!(parsed(words, &float, &["compax", "move"], &["timeout_s"]).unwrap(), [some("9.5 (default)")]);
        let whole = file.replace("drive = 3", "drive = 3.0");
        let e = parsed(words, &whole, &["compax"], &["drive"]).unwrap_err();
        assert!(format!("{e:?}").contains("'3.0' for '--drive"), "{e:?}");
        // No --device, another command: as it is.
        assert_eq!(parsed("compax --port sim status", file, &["compax"], &["port", "drive"]).unwrap()[0], some("sim"));
        // With --help: the device's values are the defaults the help shows.
        let args: Vec<OsString> =
            ["motionlink", "compax", "--device", "move", "move", "--help"].iter().map(OsString::from).collect();
        // (`move` without its target: the command line clap would refuse but for --help.)
        let cli = crate::numbers::negative_values(<crate::Cli as clap::CommandFactory>::command());
        let mut cli =
            with_device_options_from(&args, cli, Some(PathBuf::from("d.toml")), |_| Ok(file.to_string())).unwrap();
        let help = cli.find_subcommand_mut("compax").unwrap().find_subcommand_mut("move").unwrap().render_long_help();
        // The action's `--timeout-s` (600 of its own) shows the device's 9.
        assert!(help.to_string().contains("[default: 9]"), "{help}");
        // A value the option refuses is the file's mistake; the help is shown all the same.
        let bad = file.replace("drive = 3", "drive = 40");
        let e = parsed("compax --device move status", &bad, &["compax"], &["drive"]).unwrap_err().to_string();
        assert!(e.starts_with("d.toml: [device.move]: ") && e.contains("40"), "{e}");
        let args: Vec<OsString> =
            ["motionlink", "compax", "--device", "move", "--help"].iter().map(OsString::from).collect();
        let cli = <crate::Cli as clap::CommandFactory>::command();
        let unknown = format!("{file}nonsense = 1\n");
        assert!(with_device_options_from(&args, cli, Some(PathBuf::from("d.toml")), |_| Ok(unknown.clone())).is_ok());
    }
}
