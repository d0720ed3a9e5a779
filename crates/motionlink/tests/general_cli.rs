//! What the command line does the same for every family: completions, the manual page, list-ports,
//! quiet and colour options; and the user documentation, whose commands and examples are run (`docs`) and
//! whose links resolve (`doc_links`).

mod doc_links;
mod docs;

use std::process::Command;

use crate::common;

use common::BIN;

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
