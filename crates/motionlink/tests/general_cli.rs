//! What the command line does the same for every family: completions, the manual page, list-ports,
//! quiet and colour options.

use std::process::Command;

mod common;

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

#[test]
fn list_ports_prints_json_that_parses() {
    let out = run(&["list-ports", "--json"]);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for p in v.as_array().unwrap() {
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
