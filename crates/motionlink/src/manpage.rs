//! `motionlink man`: the manual pages, generated from the same clap definitions as `--help`. One page per
//! command of the tree (`motionlink.1`, `motionlink-scu.1`, `motionlink-scu-move.1`, ...), as the pages'
//! SUBCOMMANDS sections name them, each followed by the sections clap does not know: ENVIRONMENT, FILES and
//! EXIT STATUS.

use std::io::Write;
use std::path::Path;

use clap_mangen::roff::{bold, roman, Roff};
use clap_mangen::Man;

use crate::common::CliError;

/// What each exit code means (docs/cli.md, "Exit codes").
const EXIT_CODES: [(&str, &str); 5] = [
    ("0", "Success; also when stdout was closed (its reader went away) and what the command started was stopped."),
    ("1", "The device refused or reports an error, or a move did not end at its target."),
    ("2", "Usage error: a bad argument, a read-only entry, a value out of range, found before anything is sent."),
    ("3", "Transport error: the port, a timeout, a corrupt frame; also a stop that could not be confirmed."),
    (
        "128+n",
        "Ended by signal n (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP, 131 SIGQUIT, 148 Ctrl-Z), after stopping what the command \
         had started.",
    ),
];

/// The environment variables the program reads.
const ENVIRONMENT: [(&str, &str); 4] = [
    ("MOTIONLINK_PORT", "The port of a family command when neither --port nor --device is given."),
    ("MOTIONLINK_CONFIG", "The configuration file to read instead of devices.toml in the configuration directory."),
    ("NO_COLOR", "When set and not empty, --color auto does not colour (https://no-color.org)."),
    ("RUST_LOG", "The log filter of -v, -vv and -vvv (such as motionlink=debug)."),
];

/// `TP` paragraphs: a bold tag, then its text.
fn tagged(roff: &mut Roff, items: &[(&str, &str)]) {
    for (tag, text) in items {
        roff.control("TP", []);
        roff.text([bold(*tag)]);
        roff.text([roman(*text)]);
    }
}

/// The sections after clap's: ENVIRONMENT and FILES where the command opens a port (or is the top page),
/// EXIT STATUS on every page.
fn extra_sections(roff: &mut Roff, port: bool) {
    if port {
        roff.control("SH", ["ENVIRONMENT"]);
        tagged(roff, &ENVIRONMENT);
        roff.control("SH", ["FILES"]);
        tagged(
            roff,
            &[(
                "$XDG_CONFIG_HOME/motionlink/devices.toml",
                "The named devices of --device (~/.config/motionlink/devices.toml without XDG_CONFIG_HOME; \
                     ~/Library/Application Support/motionlink/devices.toml on macOS, \
                     %APPDATA%\\motionlink\\devices.toml on Windows), or the file MOTIONLINK_CONFIG names. Each \
                     [device.NAME] table gives family (scu, powercube or compax) and port, and any option of the \
                     family's commands and console by its name without the dashes (functions = \"tlt\", module = 3, \
                     max_pos = 500); an option on the command line wins.",
            )],
        );
    }
    roff.control("SH", ["EXIT STATUS"]);
    tagged(roff, &EXIT_CODES);
}

/// One command's page: clap's sections, then [`extra_sections`].
fn render(cmd: clap::Command, top: bool, out: &mut dyn Write) -> std::io::Result<()> {
    let port = top || cmd.get_arguments().any(|a| a.get_id() == "port");
    Man::new(cmd).render(out)?;
    let mut roff = Roff::default();
    extra_sections(&mut roff, port);
    roff.to_writer(out)
}

/// The tree of commands as the pages name them (`motionlink-scu-move`), help subcommands left out.
fn built(cmd: clap::Command) -> clap::Command {
    let mut cmd = cmd.disable_help_subcommand(true);
    cmd.build();
    cmd
}

/// Writes one page per command of `cmd`'s tree into `dir` (created if missing); returns how many.
fn write_tree(cmd: &clap::Command, dir: &Path, top: bool) -> std::io::Result<usize> {
    let mut written = 0;
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        written += write_tree(sub, dir, false)?;
    }
    let name = cmd.get_display_name().unwrap_or_else(|| cmd.get_name());
    let mut page = Vec::new();
    render(cmd.clone(), top, &mut page)?;
    std::fs::write(dir.join(format!("{name}.1")), page)?;
    Ok(written + 1)
}

/// `motionlink man`: the top page on stdout, or with `dir` every page of the tree written there.
pub fn run(cmd: clap::Command, dir: Option<&Path>) -> Result<(), CliError> {
    let cmd = built(cmd);
    match dir {
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|e| CliError::usage(format!("--dir {}: {e}", dir.display())))?;
            let n =
                write_tree(&cmd, dir, true).map_err(|e| CliError::usage(format!("--dir {}: {e}", dir.display())))?;
            crate::common::say(format!("motionlink: {n} manual pages written to {}", dir.display()));
            Ok(())
        }
        None => {
            // Into a buffer first: a closed pipe is then one failed write, reported as such.
            let mut page = Vec::new();
            render(cmd, true, &mut page)?;
            std::io::stdout().write_all(&page)?;
            Ok(())
        }
    }
}
