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

use crate::common::{classified, CliError};

/// Options no device entry gives: the one that names the entry; the console's serving address and its
/// opt-in to serve beyond this machine; a move's target (`--abs`, `--rel`: a device has no standing target)
/// and the hand-over of a move nothing watches (`--no-wait`): each must be said on the command line; and
/// clap's own.
const NOT_FROM_THE_FILE: [&str; 11] =
    ["device", "listen", "listen_any", "abs", "rel", "no_wait", "help", "version", "verbose", "quiet", "json"];

/// The command line with the options of the device `--device` names added, where a family command
/// (`motionlink scu ...`) or a console (`motionlink console scu ...`) names one: each key of the device's
/// entry for which the command (or its action: `move`'s `--max-pos`) has an option, unless the command line
/// gives that option itself or one that excludes it (`--no-wait` and `timeout_s`). A key that no command of
/// the family has is refused, named, with the nearest one; a value the option refuses is refused as the
/// file's. A command line that clap refuses, or that names no device, is returned as it is (clap then says
/// what is wrong).
pub fn with_device_options(args: Vec<OsString>, cli: &clap::Command) -> Result<Vec<OsString>, CliError> {
    with_device_options_from(args, cli, motionlink_link::profile::devices_path(), |p| std::fs::read_to_string(p))
}

fn with_device_options_from(
    args: Vec<OsString>,
    cli: &clap::Command,
    path: Option<PathBuf>,
    read: impl Fn(&PathBuf) -> std::io::Result<String>,
) -> Result<Vec<OsString>, CliError> {
    let Ok(matches) = cli.clone().try_get_matches_from(&args) else { return Ok(args) };
    let Some(levels) = levels(cli, &matches) else { return Ok(args) };
    let Ok(Some(name)) = levels[0].matches.try_get_one::<String>("device") else { return Ok(args) };
    let family = levels[0].family;
    let (device, shown) = load_with(family, name, path, read).map_err(|e| classified(&e))?;
    let place = format!("{shown}: [device.{name}]");
    check_keys(cli, family, &device, &place)?;
    let port = ("port".to_string(), toml::Value::from(device.port.clone()));
    let mut out = args;
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
        let words = option_words(arg, key, value).map_err(|e| CliError::usage(format!("{place}: {e}")))?;
        let at = insertion_point(cli, &out, &levels[..=depth]);
        let mut candidate = out.clone();
        candidate.splice(at..at, words);
        // What the file adds is checked here, so that its mistakes are told as the file's; an option that
        // this use of the action cannot take (one it requires is not given) is left out.
        match cli.clone().try_get_matches_from(&candidate) {
            Ok(_) => out = candidate,
            Err(e) if matches!(e.kind(), ErrorKind::MissingRequiredArgument | ErrorKind::ArgumentConflict) => {}
            Err(e) => {
                let text = e.render().to_string();
                let first = text.lines().next().unwrap_or_default().trim_start_matches("error: ");
                return Err(CliError::usage(format!("{place}: {first}")));
            }
        }
    }
    Ok(out)
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
        // The nearest key, if it is near: a third of the key's letters at most (at least one) differ.
        let near = (key.chars().count() / 3).max(1);
        let nearest = keys.iter().min_by_key(|k| edit_distance(k, key)).filter(|k| edit_distance(k, key) <= near);
        let hint = nearest.map(|k| format!(" (did you mean `{k}`?)")).unwrap_or_default();
        let why = if NOT_FROM_THE_FILE.contains(&key.as_str()) { " (give it on the command line)" } else { "" };
        return Err(CliError::usage(format!(
            "{place}: unknown key `{key}`{why}{hint}; the {family} options are: {}",
            keys.join(", ")
        )));
    }
    Ok(())
}

/// The words that give option `arg` the file's `value`: `--name=value`, once per element of an array for
/// an option that may be repeated, `--name` for a switch that is true.
fn option_words(arg: &clap::Arg, key: &str, value: &toml::Value) -> Result<Vec<OsString>, String> {
    let long = arg.get_long().ok_or_else(|| format!("`{key}` has no long option"))?;
    if !arg.get_action().takes_values() {
        return match value {
            toml::Value::Boolean(true) => Ok(vec![format!("--{long}").into()]),
            toml::Value::Boolean(false) => Ok(Vec::new()),
            other => Err(format!("`{key}` is a switch: give true or false, not {}", shown(other))),
        };
    }
    let scalar = |v: &toml::Value| match v {
        toml::Value::String(s) => Ok(s.clone()),
        toml::Value::Integer(i) => Ok(i.to_string()),
        toml::Value::Float(f) => Ok(f.to_string()),
        other => Err(format!("`{key}` = {}: give a string or a number", shown(other))),
    };
    match value {
        toml::Value::Array(items) if matches!(arg.get_action(), clap::ArgAction::Append) => {
            items.iter().map(|v| Ok(format!("--{long}={}", scalar(v)?).into())).collect()
        }
        toml::Value::Array(_) => Err(format!("`{key}` takes one value, not a list")),
        v => Ok(vec![format!("--{long}={}", scalar(v)?).into()]),
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

/// The number of single-character edits between `a` and `b`.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let next = (diagonal + usize::from(ca != *cb)).min(row[j] + 1).min(row[j + 1] + 1);
            diagonal = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line `words` with the options of `file`'s device added.
    fn with_file(words: &str, file: &str) -> Result<Vec<String>, CliError> {
        let args: Vec<OsString> = std::iter::once("motionlink").chain(words.split(' ')).map(OsString::from).collect();
        let cli = <crate::Cli as clap::CommandFactory>::command();
        let out = with_device_options_from(args, &cli, Some(PathBuf::from("d.toml")), |_| Ok(file.to_string()))?;
        Ok(out.iter().skip(1).map(|w| w.to_string_lossy().into_owned()).collect())
    }

    #[test]
    fn a_devices_options_go_after_the_words_of_their_command() {
        let file = "[device.move]\nfamily = \"compax\"\nport = \"sim\"\ndrive = 3\nmax_pos = 50\ntimeout_s = 9\n";
        // The family's option after `compax`, the action's after `move` (not after the device named move).
        assert_eq!(
            with_file("--color never compax --device move move --abs 5", file).unwrap(),
            [
                "--color",
                "never",
                "compax",
                "--port=sim",
                "--drive=3",
                "--device",
                "move",
                "move",
                "--timeout-s=9",
                "--max-pos=50",
                "--abs",
                "5"
            ]
        );
        // Given on the command line, or excluded by what is: left out.
        assert_eq!(
            with_file("compax --device move move --abs 5 --no-wait --drive 1 --max-pos 60", file).unwrap(),
            [
                "compax",
                "--port=sim",
                "--device",
                "move",
                "move",
                "--abs",
                "5",
                "--no-wait",
                "--drive",
                "1",
                "--max-pos",
                "60"
            ]
        );
        // The console: its own options (max_pos), not the command's (drive).
        assert_eq!(
            with_file("console compax --device move", file).unwrap(),
            ["console", "compax", "--port=sim", "--max-pos=50", "--device", "move"]
        );
        // No --device, another command: as it is.
        assert_eq!(with_file("compax --port sim status", file).unwrap(), ["compax", "--port", "sim", "status"]);
        assert_eq!(with_file("decode compax", file).unwrap(), ["decode", "compax"]);
    }

    #[test]
    fn edit_distance_counts_single_edits() {
        assert_eq!(edit_distance("functions", "functoins"), 2);
        assert_eq!(edit_distance("module", "modules"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("baud", "baud"), 0);
    }
}
