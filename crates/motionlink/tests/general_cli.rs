//! What the command line does the same for every family: completions, the manual page, list-ports,
//! quiet and colour options.

use std::process::Command;
use std::time::Duration;

use crate::common;

use common::{Sim, BIN};

fn run(args: &[&str]) -> std::process::Output {
    Command::new(BIN).args(args).env_remove("NO_COLOR").output().unwrap()
}

#[test]
fn completions_for_the_usual_shells_name_every_family() {
    for (shell, marker) in
        [("bash", "_motionlink()"), ("zsh", "#compdef motionlink"), ("fish", "complete -c motionlink")]
    {
        let out = run(&["completions", shell]);
        assert!(out.status.success(), "{shell}: {out:?}");
        let script = String::from_utf8(out.stdout).unwrap();
        assert!(script.contains(marker), "{shell}: {}", &script[..script.len().min(200)]);
        for family in ["scu", "powercube", "compax", "decode", "sim"] {
            assert!(script.contains(family), "{shell} completion lacks {family}");
        }
    }
    assert_eq!(run(&["completions", "tcsh"]).status.code(), Some(2), "an unknown shell is a usage error");
}

#[test]
fn the_manual_page_comes_from_the_same_definitions() {
    let out = run(&["man"]);
    assert!(out.status.success());
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(page.contains(".TH motionlink 1"), "{}", &page[..200]);
    for word in ["scu", "powercube", "compax", "list\\-ports", "\\-\\-color"] {
        assert!(page.contains(word), "the page lacks {word}");
    }
}

/// `man --dir` writes the page of every command the pages name: the families' pages have `--port` and
/// their actions, every page its EXIT STATUS, the top page ENVIRONMENT and FILES.
#[test]
fn the_manual_pages_cover_the_whole_tree() {
    let dir = common::temp_path("man");
    let out = run(&["man", "--dir", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{out:?}");
    let page =
        |name: &str| std::fs::read_to_string(dir.join(format!("{name}.1"))).unwrap_or_else(|e| panic!("{name}.1: {e}"));
    let top = page("motionlink");
    for family in ["scu", "powercube", "compax"] {
        assert!(top.contains(&format!("motionlink\\-{family}(1)")), "the top page names {family}'s page");
        let p = page(&format!("motionlink-{family}"));
        assert!(p.contains("\\-\\-port"), "{family}: --port");
        for action in ["get", "set", "send", "watch", "move"] {
            assert!(p.contains(&format!("motionlink\\-{family}\\-{action}(1)")), "{family} {action}");
            page(&format!("motionlink-{family}-{action}"));
        }
        assert!(p.contains("MOTIONLINK_PORT"), "{family}: ENVIRONMENT");
    }
    assert!(page("motionlink-scu-move").contains("\\-\\-speed"));
    for section in ["ENVIRONMENT", "FILES", "EXIT STATUS", "MOTIONLINK_CONFIG", "NO_COLOR", "devices.toml", "128+n"] {
        assert!(top.contains(section), "the top page lacks {section}");
    }
    for code in ["0", "1", "2", "3"] {
        assert!(top.contains(&format!(".TP\n\\fB{code}\\fR")), "exit code {code}: {top}");
    }
    assert!(page("motionlink-decode-scu").contains("EXIT STATUS"));
    let _ = std::fs::remove_dir_all(&dir);
    // On stdout: the top page with the same sections.
    let out = run(&["man"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("EXIT STATUS"), "{out:?}");
}

/// `--color` reaches clap's own messages too (a usage error clap finds), read before clap parses.
#[test]
fn clap_messages_follow_the_color_option() {
    let bad = ["scu", "--no-such-option"];
    let colored = |args: &[&str], env: &[(&str, &str)]| {
        let o = common::run_with(args, env, "");
        assert_eq!(o.status.code(), Some(2), "{o:?}");
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(err.contains("no-such-option"), "{err}");
        err.contains('\x1b')
    };
    assert!(colored(&[&["--color", "always"][..], &bad].concat(), &[]), "--color always: ANSI even into a pipe");
    assert!(colored(&[&bad[..], &["--color=always"]].concat(), &[]), "after the action, as --color=always");
    assert!(!colored(&[&["--color", "never"][..], &bad].concat(), &[]), "--color never: none");
    assert!(!colored(&bad, &[]), "auto into a pipe: none");
    assert!(!colored(&[&["--color", "auto"][..], &bad].concat(), &[("NO_COLOR", "1")]), "NO_COLOR");
}

#[test]
fn list_ports_prints_json_that_parses() {
    let out = run(&["list-ports", "--json"]);
    assert!(out.status.success(), "{out:?}");
    // One object per port (JSON Lines).
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let p: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(p["port"].is_string() && ["serial", "can"].contains(&p["kind"].as_str().unwrap()), "{p}");
    }
}

#[test]
fn errors_are_red_only_when_asked_and_quiet_keeps_them() {
    // A usage error found before anything is opened.
    let args = ["scu", "--port", "sim", "get", "no_such_entry"];
    let plain = run(&args);
    assert_eq!(plain.status.code(), Some(2));
    let text = String::from_utf8_lossy(&plain.stderr);
    assert!(text.contains("no_such_entry") && !text.contains('\x1b'), "not a terminal: no colour: {text:?}");

    let mut always = vec!["--color", "always"];
    always.extend_from_slice(&args);
    let red = String::from_utf8_lossy(&run(&always).stderr).to_string();
    assert!(red.contains("\x1b[31m"), "{red:?}");
    let no_color = Command::new(BIN).args(["--color", "auto"]).args(args).env("NO_COLOR", "1").output().unwrap();
    assert!(!String::from_utf8_lossy(&no_color.stderr).contains('\x1b'));

    let mut quiet = vec!["-q"];
    quiet.extend_from_slice(&args);
    let q = run(&quiet);
    assert_eq!(q.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&q.stderr).contains("no_such_entry"), "-q still prints the error");
    assert_eq!(run(&["-q", "-v", "list-ports"]).status.code(), Some(2), "-q and -v contradict each other");
}

/// Splits a README command line as a shell would for these simple lines: words, "double quoted" words, a
/// trailing `# comment` dropped.
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

/// Every command of the README's ```sh and ```console blocks that starts with `motionlink` runs against
/// `motionlink sim` and succeeds (`--port` other than `sim` becomes the emulator of the family; a `sim`
/// server must print its listening line); in a ```console block, the lines after `$ motionlink ...` are its
/// exact output. So the documentation cannot rot.
#[test]
fn every_readme_command_runs_against_the_emulators() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../README.md")).unwrap();
    // The commands, each with the output a console block shows for it.
    let mut commands: Vec<(String, Vec<String>)> = Vec::new();
    let mut block: Option<bool> = None; // Some(console?)
    for line in readme.lines() {
        let t = line.trim();
        match (&block, t) {
            (None, "```sh") => block = Some(false),
            (None, "```console") => block = Some(true),
            (None, _) => {}
            (Some(_), "```") => block = None,
            (Some(console), t) => {
                let command = if *console { t.strip_prefix("$ ") } else { Some(t) };
                match command {
                    Some(c) if c.starts_with("motionlink ") => commands.push((c.to_string(), Vec::new())),
                    Some(_) => {}
                    None if *console && !t.is_empty() => {
                        if let Some(last) = commands.last_mut() {
                            last.1.push(t.to_string());
                        }
                    }
                    None => {}
                }
            }
        }
    }
    assert!(commands.len() > 40, "{} commands found", commands.len());
    let scu = Sim::start("scu", &["--tcp", "127.0.0.1:0"]);
    let tlt = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--preset", "tlt"]);
    let powercube = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--modules", "1,17"]);
    let compax = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1,5"]);
    let dir = std::env::temp_dir().join(format!("motionlink-readme-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("targets.txt"), "400\n410\n").unwrap();
    // The README's TOML blocks are the fixtures: the SCU emulator's configuration is the `unit.toml` its
    // `sim scu --config unit.toml` reads (the real parser: a key it does not know fails the command).
    let tomls = readme_blocks(&readme, "```toml");
    let unit = tomls.iter().find(|b| b.contains("[[actuator]]")).expect("the README's SCU emulator TOML");
    std::fs::write(dir.join("unit.toml"), unit).unwrap();
    // The commands of one emulator (and the decode of what they captured) run in the README's order; the
    // groups run side by side, so the test takes as long as its longest group, not the sum of all.
    let mut groups: Vec<(String, Vec<&ReadmeCommand>)> = Vec::new();
    for command in &commands {
        let key = readme_group(&command.0);
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
                        .filter_map(|(line, expected)| {
                            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                                run_readme_command(line, expected, [scu, tlt, powercube, compax], dir)
                            }))
                            .err()
                            .map(|e| {
                                e.downcast_ref::<String>()
                                    .cloned()
                                    .unwrap_or_else(|| format!("README: {line}: panicked"))
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

/// The text of every block of `readme` that opens with the line `fence` (such as "```toml").
fn readme_blocks(readme: &str, fence: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in readme.lines() {
        match (&mut current, line.trim()) {
            (None, t) if t == fence => current = Some(String::new()),
            (Some(_), "```") => blocks.extend(current.take()),
            (Some(text), _) => {
                text.push_str(line);
                text.push('\n');
            }
            (None, _) => {}
        }
    }
    blocks
}

/// The README's devices.toml, read by the real parser: each device it names, its port pointed at the
/// emulator of its family, answers through `--device`.
#[test]
fn the_readme_devices_toml_names_devices_that_answer() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../README.md")).unwrap();
    let tomls = readme_blocks(&readme, "```toml");
    assert_eq!(tomls.len(), 2, "the README's TOML blocks: devices.toml and the SCU emulator's: {tomls:?}");
    let devices = tomls.iter().find(|b| b.contains("[device.")).expect("the README's devices.toml");
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
    let config = common::temp_path("readme-devices.toml");
    std::fs::write(&config, &text).unwrap();
    let cfg = config.to_str().unwrap();
    for args in
        [&["scu", "--device", "lift", "get", "firmware_info"][..], &["powercube", "--device", "arm", "get", "ActPos"]]
    {
        let o = common::run_with(args, &[("MOTIONLINK_CONFIG", cfg)], "");
        assert!(o.status.success(), "{args:?} with the README's devices.toml: {o:?}\n{text}");
    }
    // The family check the comment promises: lift is an SCU, refused for powercube.
    let o = common::run_with(&["powercube", "--device", "lift", "get", "ActPos"], &[("MOTIONLINK_CONFIG", cfg)], "");
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let _ = std::fs::remove_file(&config);
}

/// A README command line and the output its ```console block shows (if any).
type ReadmeCommand = (String, Vec<String>);

/// Which README commands must run one after the other: those of one emulator (a `--port` command's family,
/// the TLT preset apart), and a `decode` with its family's commands (it reads what they captured).
fn readme_group(line: &str) -> String {
    let words = shell_words(line);
    let family = if matches!(words[1].as_str(), "console" | "decode" | "sim") { 2 } else { 1 };
    let family = words.get(family).cloned().unwrap_or_default();
    if words[1] == "sim" || words.iter().any(|w| w == "sim") {
        format!("{family} in its own process")
    } else if line.contains("--functions tlt") {
        "scu tlt".into()
    } else {
        family
    }
}

/// Runs one README command against the emulators (`[scu, tlt, powercube, compax]`) with the fixtures in
/// `dir`, and checks its exit status and, where the README shows it, its output.
fn run_readme_command(line: &str, expected: &[String], sims: [&Sim; 4], dir: &std::path::Path) {
    let [scu, tlt, powercube, compax] = sims;
    let mut words = shell_words(line);
    let mut stdin = String::new();
    if let Some(i) = words.iter().position(|w| w == "<") {
        stdin = std::fs::read_to_string(dir.join(&words[i + 1])).unwrap_or_else(|e| panic!("{line}: {e}"));
        words.truncate(i);
    }
    if let Some(i) = words.iter().position(|w| w == "--port") {
        // `motionlink console <family> ...` names its family one word later.
        let family = if words[1] == "console" { words[2].as_str() } else { words[1].as_str() };
        let sim = match family {
            "scu" if line.contains("--functions tlt") => tlt,
            "scu" => scu,
            "powercube" => powercube,
            "compax" => compax,
            other => panic!("{line}: --port for {other}"),
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
        assert!(listening.is_some(), "{line}: no listening line; {}", running.stderr.text());
        return;
    }
    if args[0] == "console" {
        // A server: it runs until stopped; what the README promises is its one line.
        let running = common::Running::start(&args);
        let line_out = running.stdout.wait_for(Duration::from_secs(20), |l| l.starts_with("console on http://"));
        assert!(line_out.is_some(), "{line}: no `console on` line; {}", running.stderr.text());
        return;
    }
    let mut child = Command::new(BIN)
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
    assert!(out.status.success(), "README: {line}\n{:?}\n{text}{}", out.status, String::from_utf8_lossy(&out.stderr));
    if !expected.is_empty() {
        let norm = |s: &str| s.split_whitespace().collect::<Vec<_>>().join(" ");
        let got: Vec<String> = text.lines().map(norm).collect();
        let want: Vec<String> = expected.iter().map(|l| norm(l)).collect();
        assert_eq!(got, want, "README: {line}");
    }
}

#[test]
fn demo_with_json_prints_each_telegram_as_an_object() {
    let out = Command::new(BIN).args(["demo", "--json"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let objects: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON: {l}: {e}")))
        .collect();
    let telegrams = |family: &str| -> Vec<&serde_json::Value> {
        objects.iter().filter(|o| o["family"] == family && o["bytes"].is_string()).collect()
    };
    // The SCU manual's RO 00 example, byte for byte; the routine's telegrams carry device time.
    let scu = telegrams("scu");
    assert!(scu.iter().any(|o| o["bytes"] == "52 4F 00 5C 2D" && o["step"] == "RO 00" && o["direction"] == "->"));
    assert!(scu.iter().any(|o| o["time_s"].is_f64() && o["direction"] == "<-"), "replies with their time");
    // PowerCube: CAN frames and RS232 bytes, each under the manual's step name.
    let powercube = telegrams("powercube");
    assert!(powercube.iter().any(|o| o["step"] == "Home" && o["meaning"].as_str().is_some_and(|m| !m.is_empty())));
    assert!(!telegrams("compax").is_empty());
    // Nothing else than telegrams and notes; no colour codes.
    assert!(objects.iter().all(|o| o["bytes"].is_string() || o["note"].is_string()), "{objects:?}");
    assert!(!String::from_utf8_lossy(&out.stdout).contains('\x1b'));
}
