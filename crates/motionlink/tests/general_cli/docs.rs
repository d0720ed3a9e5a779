//! The user documentation (README.md and every page of docs/) is run: its commands against the emulators,
//! its TOML blocks as the fixtures they describe, its Rust blocks checked against the doctests they copy.
//! A block that no test runs must say so (```text, or `not-run` after the language); any other block fails.

use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::common;

use common::{Sim, BIN};

/// The repository's root directory.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A page of the user documentation.
pub struct Page {
    /// Its path from the repository's root: `README.md`, `docs/scu.md`.
    pub path: String,
    /// Its text.
    pub text: String,
}

/// The user documentation: README.md, then the pages of docs/ in name order.
pub fn pages() -> Vec<Page> {
    let root = repo_root();
    let mut names: Vec<String> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    names.sort();
    names.insert(0, "README.md".into());
    names
        .into_iter()
        .map(|path| {
            let text = std::fs::read_to_string(root.join(&path)).unwrap_or_else(|e| panic!("{path}: {e}"));
            Page { path, text }
        })
        .collect()
}

/// A fenced code block of a page.
pub struct Block<'a> {
    /// Where it is: `docs/scu.md:42` (the line of its opening fence).
    pub place: String,
    /// The first word of its info string: `sh`, `console`, `toml`, `python`, `rust`, `text` (`""` if none).
    pub lang: String,
    /// `not-run` after the language: no test runs it, on purpose.
    pub not_run: bool,
    /// The HTML comment on the line before the fence (`<!-- doctest: FILE -->`), if any.
    pub marker: Option<&'a str>,
    /// Its lines.
    pub lines: Vec<&'a str>,
}

/// The fenced code blocks of `page`, in order. An info string with anything but `not-run` after the
/// language, or a block that is never closed, is an error naming the place.
pub fn blocks(page: &Page) -> Result<Vec<Block<'_>>, String> {
    let mut found = Vec::new();
    let mut open: Option<Block> = None;
    let mut previous: Option<&str> = None;
    for (i, line) in page.text.lines().enumerate() {
        let t = line.trim();
        match open.as_mut() {
            Some(_) if t == "```" => found.extend(open.take()),
            Some(block) => block.lines.push(line),
            None if t.starts_with("```") => {
                let place = format!("{}:{}", page.path, i + 1);
                let mut words = t[3..].split_whitespace();
                let lang = words.next().unwrap_or("").to_string();
                let rest: Vec<&str> = words.collect();
                let not_run = match rest.as_slice() {
                    [] => false,
                    ["not-run"] => true,
                    other => return Err(format!("{place}: `{other:?}` after the language: only `not-run` is known")),
                };
                let marker = previous.filter(|p| p.starts_with("<!--"));
                open = Some(Block { place, lang, not_run, marker, lines: Vec::new() });
            }
            None => {}
        }
        if !t.is_empty() {
            previous = Some(t);
        }
    }
    match open {
        Some(block) => Err(format!("{}: a block that is never closed", block.place)),
        None => Ok(found),
    }
}

/// Every block of every page.
fn all_blocks(pages: &[Page]) -> Vec<Block<'_>> {
    pages.iter().flat_map(|p| blocks(p).unwrap_or_else(|e| panic!("{e}"))).collect()
}

/// What a TOML block of the documentation is: the fixture the tests read it as.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fixture {
    /// The configuration file of `--device` (`[device.NAME]` tables).
    Devices,
    /// The SCU emulator's `unit.toml` (`[[actuator]]` tables).
    ScuUnit,
}

fn fixture(text: &str) -> Option<Fixture> {
    if text.contains("[device.") {
        Some(Fixture::Devices)
    } else if text.contains("[[actuator]]") {
        Some(Fixture::ScuUnit)
    } else {
        None
    }
}

/// The text of the one TOML block of the documentation that is `which` fixture.
fn fixture_text(pages: &[Page], which: Fixture) -> String {
    let found: Vec<String> = all_blocks(pages)
        .into_iter()
        .filter(|b| b.lang == "toml" && !b.not_run && fixture(&b.lines.join("\n")) == Some(which))
        .map(|b| b.lines.iter().map(|l| format!("{l}\n")).collect())
        .collect();
    assert_eq!(found.len(), 1, "exactly one {which:?} TOML block in the documentation: {found:?}");
    found.into_iter().next().unwrap()
}

/// Checks that `block` (a Rust block marked `<!-- doctest: FILE -->`) is, line for line, the code of a
/// doctest in FILE that is compiled (not `ignore`, not `text`).
fn check_doctest(block: &Block, marker: &str) -> Result<(), String> {
    let file = marker
        .strip_prefix("<!-- doctest:")
        .and_then(|m| m.strip_suffix("-->"))
        .map(str::trim)
        .ok_or_else(|| format!("{}: a Rust block needs `<!-- doctest: FILE -->` or `not-run`", block.place))?;
    let source =
        std::fs::read_to_string(repo_root().join(file)).map_err(|e| format!("{}: {file}: {e}", block.place))?;
    // The documentation comments' text, as rustdoc sees it.
    let doc: Vec<&str> = source
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            l.strip_prefix("//!").or_else(|| l.strip_prefix("///"))
        })
        .map(|l| l.strip_prefix(' ').unwrap_or(l))
        .collect();
    let want: Vec<&str> = block.lines.iter().map(|l| l.trim_end()).collect();
    let at = (0..=doc.len().saturating_sub(want.len()))
        .filter(|&i| !want.is_empty() && i + want.len() <= doc.len())
        .find(|&i| doc[i..i + want.len()].iter().map(|l| l.trim_end()).eq(want.iter().copied()))
        .ok_or_else(|| format!("{}: the block is not the code of a doctest in {file}", block.place))?;
    let fence = doc[..at].iter().rev().find(|l| l.trim_start().starts_with("```")).copied().unwrap_or("");
    if fence.contains("ignore") || fence.contains("text") {
        return Err(format!("{}: the doctest in {file} is not compiled ({fence})", block.place));
    }
    Ok(())
}

/// Every block of the documentation is run by a test, or says that it is not: ```text, or `not-run`
/// after the language. A ```sh block holds only `motionlink` commands (and `#` comments), a ```console
/// block only `$ motionlink` commands and their output, a TOML block is a fixture the tests read, a
/// ```python block is run by python/tests/test_readme.py, a ```rust block is a doctest's code.
#[test]
fn every_doc_block_is_run_or_marked() {
    let pages = pages();
    let mut errors = Vec::new();
    let mut fixtures = Vec::new();
    for block in all_blocks(&pages) {
        if block.not_run || block.lang == "text" {
            continue;
        }
        let place = &block.place;
        match block.lang.as_str() {
            "sh" => {
                for l in block.lines.iter().map(|l| l.trim()).filter(|l| !l.is_empty() && !l.starts_with('#')) {
                    if !l.starts_with("motionlink ") {
                        errors.push(format!("{place}: `{l}` is no motionlink command: mark the block ```sh not-run"));
                    }
                }
            }
            "console" => {
                let first = block.lines.iter().map(|l| l.trim()).find(|l| !l.is_empty()).unwrap_or("");
                if !first.starts_with("$ ") {
                    errors.push(format!("{place}: a ```console block starts with its `$ motionlink` command"));
                }
                for l in block.lines.iter().filter_map(|l| l.trim().strip_prefix("$ ")) {
                    if !l.starts_with("motionlink ") {
                        errors.push(format!("{place}: `$ {l}` is no motionlink command"));
                    }
                }
            }
            "toml" => match fixture(&block.lines.join("\n")) {
                Some(f) => fixtures.push(f),
                None => errors.push(format!("{place}: a TOML block that no test reads: mark it ```toml not-run")),
            },
            "python" => match block.marker {
                None | Some("<!-- python-example -->") | Some("<!-- python-fixture -->") => {}
                Some(other) => errors.push(format!("{place}: {other}: not a marker python/tests/test_readme.py knows")),
            },
            "rust" => {
                if let Err(e) = check_doctest(&block, block.marker.unwrap_or("")) {
                    errors.push(e);
                }
            }
            "" => errors.push(format!("{place}: a block without a language: ```text if it is not run")),
            other => errors.push(format!("{place}: no test runs ```{other} blocks: mark it ```{other} not-run")),
        }
    }
    for f in [Fixture::Devices, Fixture::ScuUnit] {
        let n = fixtures.iter().filter(|&&g| g == f).count();
        if n != 1 {
            errors.push(format!("{n} TOML blocks are the {f:?} fixture: the tests read exactly one"));
        }
    }
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

/// The check above fails when it should: a shell line that is not a command, an unknown language, a Rust
/// block that copies no doctest, a TOML block no test reads.
#[test]
fn the_block_rules_refuse_what_no_test_runs() {
    let page = |text: &str| Page { path: "x.md".into(), text: text.into() };
    let sh = page("```sh\ncargo build\n```\n");
    assert_eq!(blocks(&sh).unwrap()[0].lines, ["cargo build"]);
    assert!(!blocks(&sh).unwrap()[0].not_run);
    assert!(blocks(&page("```sh not-run\ncargo build\n```\n")).unwrap()[0].not_run);
    assert!(blocks(&page("```sh skip\nx\n```\n")).is_err(), "only not-run is known");
    assert!(blocks(&page("```sh\nx\n")).is_err(), "a block never closed");
    let rust = page("<!-- doctest: crates/motionlink-scu/src/client/mod.rs -->\n```rust\nlet x = 1;\n```\n");
    let b = &blocks(&rust).unwrap()[0];
    assert!(check_doctest(b, b.marker.unwrap()).is_err(), "code that is in no doctest");
    assert!(check_doctest(b, "").is_err(), "no marker");
    let copied = page(
        "<!-- doctest: crates/motionlink-scu/src/client/mod.rs -->\n```rust\n\
         let a1 = Actuator::new(1).unwrap();\n```\n",
    );
    let b = &blocks(&copied).unwrap()[0];
    assert_eq!(check_doctest(b, b.marker.unwrap()), Ok(()));
    assert_eq!(fixture("[x]\na = 1\n"), None);
}

/// Splits a documented command line as a shell would for these simple lines: words, "double quoted" words,
/// a trailing `# comment` dropped.
fn shell_words(line: &str) -> Vec<String> {
    let (mut words, mut word, mut quoted, mut in_word) = (Vec::new(), String::new(), false, false);
    for c in line.chars() {
        match c {
            '"' => {
                quoted = !quoted;
                in_word = true;
            }
            '#' if !quoted && !in_word => break,
            c if c.is_whitespace() && !quoted => {
                if in_word {
                    words.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            c => {
                word.push(c);
                in_word = true;
            }
        }
    }
    if in_word {
        words.push(word);
    }
    words
}

/// A documented command line (with its place) and the output its ```console block shows (if any).
struct DocCommand {
    place: String,
    line: String,
    output: Vec<String>,
}

/// The `motionlink` commands of every ```sh and ```console block that is run, page by page in order.
fn doc_commands(pages: &[Page]) -> Vec<DocCommand> {
    let mut commands: Vec<DocCommand> = Vec::new();
    for block in all_blocks(pages).into_iter().filter(|b| !b.not_run) {
        let console = match block.lang.as_str() {
            "sh" => false,
            "console" => true,
            _ => continue,
        };
        for t in block.lines.iter().map(|l| l.trim()) {
            let command = if console { t.strip_prefix("$ ") } else { Some(t) };
            match command {
                Some(c) if c.starts_with("motionlink ") => {
                    commands.push(DocCommand { place: block.place.clone(), line: c.into(), output: Vec::new() })
                }
                Some(_) => {}
                None if !t.is_empty() => commands.last_mut().expect("output after a command").output.push(t.into()),
                None => {}
            }
        }
    }
    commands
}

/// Every command of the documentation's ```sh and ```console blocks that starts with `motionlink` runs
/// against `motionlink sim` and succeeds (`--port` other than `sim` becomes the emulator of the family, a
/// TLT column pair for an SCU command with `--functions tlt`; a `sim` server must print its listening
/// line); in a ```console block, the lines after `$ motionlink ...` are its exact output. So the
/// documentation cannot rot.
#[test]
fn every_doc_command_runs_against_the_emulators() {
    let pages = pages();
    let commands = doc_commands(&pages);
    assert!(commands.len() > 60, "{} commands found", commands.len());
    assert!(
        commands.iter().any(|c| c.place.starts_with("README.md") && c.line.contains("--functions tlt move 1 400")),
        "the README's quick start moves a TLT column pair"
    );
    let scu = Sim::start("scu", &["--tcp", "127.0.0.1:0"]);
    let tlt = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--preset", "tlt"]);
    let powercube = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--modules", "1,17"]);
    let compax = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1,5"]);
    let dir = std::env::temp_dir().join(format!("motionlink-docs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("targets.txt"), "400\n410\n").unwrap();
    // The TOML blocks are the fixtures: the SCU emulator's configuration is the `unit.toml` its
    // `sim scu --config unit.toml` reads (the real parser: a key it does not know fails the command).
    std::fs::write(dir.join("unit.toml"), fixture_text(&pages, Fixture::ScuUnit)).unwrap();
    // The commands of one emulator (and the decode of what they captured) run in the pages' order; the
    // groups run side by side, so the test takes as long as its longest group, not the sum of all.
    let mut groups: Vec<(String, Vec<&DocCommand>)> = Vec::new();
    for command in &commands {
        let key = doc_group(&command.line);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, list)) => list.push(command),
            None => groups.push((key, vec![command])),
        }
    }
    let failures: Vec<String> = std::thread::scope(|scope| {
        let running: Vec<_> = groups
            .iter()
            .map(|(_, list)| {
                let (scu, tlt, powercube, compax, dir) = (&scu, &tlt, &powercube, &compax, &dir);
                scope.spawn(move || {
                    list.iter()
                        .filter_map(|c| {
                            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                                run_doc_command(c, [scu, tlt, powercube, compax], dir)
                            }))
                            .err()
                            .map(|e| {
                                e.downcast_ref::<String>()
                                    .cloned()
                                    .unwrap_or_else(|| format!("{}: {}: panicked", c.place, c.line))
                            })
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        running.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The documented devices.toml, read by the real parser: each device it names, its port pointed at the
/// emulator of its family, answers through `--device`.
#[test]
fn the_documented_devices_toml_names_devices_that_answer() {
    let devices = fixture_text(&pages(), Fixture::Devices);
    let scu = Sim::tcp("scu");
    let powercube = Sim::tcp("powercube");
    let mut text = devices.clone();
    for (family, sim) in [("scu", &scu), ("powercube", &powercube)] {
        // The port line after `family = "<family>"` becomes the emulator's address.
        let at = text.find(&format!("family = \"{family}\"")).unwrap_or_else(|| panic!("no {family} device"));
        let port_at = at + text[at..].find("port = \"").unwrap() + "port = \"".len();
        let end = port_at + text[port_at..].find('"').unwrap();
        text.replace_range(port_at..end, &sim.address);
    }
    let config = common::temp_path("docs-devices.toml");
    std::fs::write(&config, &text).unwrap();
    let cfg = config.to_str().unwrap();
    for args in
        [&["scu", "--device", "lift", "get", "firmware_info"][..], &["powercube", "--device", "arm", "get", "ActPos"]]
    {
        let o = common::run_with(args, &[("MOTIONLINK_CONFIG", cfg)], "");
        assert!(o.status.success(), "{args:?} with the documented devices.toml: {o:?}\n{text}");
    }
    // The family check the comment promises: lift is an SCU, refused for powercube.
    let o = common::run_with(&["powercube", "--device", "lift", "get", "ActPos"], &[("MOTIONLINK_CONFIG", cfg)], "");
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let _ = std::fs::remove_file(&config);
}

/// Which documented commands must run one after the other: those of one emulator (a `--port` command's
/// family, the TLT preset apart), and a `decode` with its family's commands (it reads what they captured).
fn doc_group(line: &str) -> String {
    let words = shell_words(line);
    let family = if matches!(words[1].as_str(), "console" | "decode" | "sim" | "probe") { 2 } else { 1 };
    let family = words.get(family).cloned().unwrap_or_default();
    if words[1] == "sim" || words.iter().any(|w| w == "sim") {
        format!("{family} in its own process")
    } else if line.contains("--functions tlt") {
        "scu tlt".into()
    } else {
        family
    }
}

/// Runs one documented command against the emulators (`[scu, tlt, powercube, compax]`) with the fixtures
/// in `dir`, and checks its exit status and, where the page shows it, its output.
fn run_doc_command(command: &DocCommand, sims: [&Sim; 4], dir: &Path) {
    let [scu, tlt, powercube, compax] = sims;
    let (place, line) = (&command.place, &command.line);
    let mut words = shell_words(line);
    let mut stdin = String::new();
    if let Some(i) = words.iter().position(|w| w == "<") {
        stdin = std::fs::read_to_string(dir.join(&words[i + 1])).unwrap_or_else(|e| panic!("{place}: {line}: {e}"));
        words.truncate(i);
    }
    if let Some(i) = words.iter().position(|w| w == "--port") {
        // `motionlink console <family> ...` and `motionlink probe <family> ...` name their family one word
        // later.
        let family =
            if matches!(words[1].as_str(), "console" | "probe") { words[2].as_str() } else { words[1].as_str() };
        let sim = match family {
            "scu" if line.contains("--functions tlt") => tlt,
            "scu" => scu,
            "powercube" => powercube,
            "compax" => compax,
            other => panic!("{place}: {line}: --port for {other}"),
        };
        if words[i + 1] != "sim" {
            words[i + 1] = sim.address.clone();
        }
    }
    // Files the examples name (unit.toml) are the fixtures in `dir`.
    for w in words.iter_mut().skip(2) {
        if !w.starts_with('-') && dir.join(&*w).is_file() {
            *w = dir.join(&*w).to_string_lossy().into_owned();
        }
    }
    let args: Vec<&str> = words[1..].iter().map(String::as_str).collect();
    if args[0] == "sim" {
        let running = common::Running::start(&args);
        let listening = running.stdout.wait_for(Duration::from_secs(10), |l| l.starts_with("listening on "));
        assert!(listening.is_some(), "{place}: {line}: no listening line; {}", running.stderr.text());
        return;
    }
    if args[0] == "console" {
        // A server: it runs until stopped; what the page promises is its one line.
        let running = common::Running::start(&args);
        let line_out = running.stdout.wait_for(Duration::from_secs(20), |l| l.starts_with("console on http://"));
        assert!(line_out.is_some(), "{place}: {line}: no `console on` line; {}", running.stderr.text());
        return;
    }
    let mut child = std::process::Command::new(BIN)
        .args(&args)
        .current_dir(dir)
        .env_remove("MOTIONLINK_PORT")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(&mut child.stdin.take().unwrap(), stdin.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{place}: {line}\n{:?}\n{text}{err}", out.status);
    if !command.output.is_empty() {
        let norm = |s: &str| s.split_whitespace().collect::<Vec<_>>().join(" ");
        let got: Vec<String> = text.lines().map(norm).collect();
        let want: Vec<String> = command.output.iter().map(|l| norm(l)).collect();
        assert_eq!(got, want, "{place}: {line}");
    }
}
