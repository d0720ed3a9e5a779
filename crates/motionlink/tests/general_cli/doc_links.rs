//! The links of the user documentation resolve: every relative link of README.md and docs/*.md names a
//! file of the repository, and every `#anchor` a heading of its page, as GitHub renders them.

use std::collections::HashSet;

use super::docs::{pages, repo_root};

/// The text of `markdown` outside fenced code blocks, HTML comments and code spans.
fn prose(markdown: &str) -> String {
    let mut text = String::new();
    let mut fenced = false;
    for line in markdown.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            text.push_str(line);
            text.push('\n');
        }
    }
    // Code spans: a run of n backticks up to the next run of exactly n (CommonMark); an unmatched run stays.
    let chars: Vec<char> = text.chars().collect();
    let run_at = |i: usize| chars[i..].iter().take_while(|&&c| c == '`').count();
    let (mut out, mut i) = (String::new(), 0);
    while i < chars.len() {
        if chars[i] != '`' {
            out.push(chars[i]);
            i += 1;
            continue;
        }
        let n = run_at(i);
        let mut j = i + n;
        let close = loop {
            match chars[j..].iter().position(|&c| c == '`') {
                None => break None,
                Some(k) => {
                    let m = run_at(j + k);
                    if m == n {
                        break Some(j + k + m);
                    }
                    j += k + m;
                }
            }
        };
        match close {
            Some(end) => i = end,
            None => {
                out.extend(&chars[i..i + n]);
                i += n;
            }
        }
    }
    while let (Some(a), Some(b)) = (out.find("<!--"), out.find("-->")) {
        if b < a {
            break;
        }
        out.replace_range(a..b + 3, "");
    }
    out
}

/// The targets of the links and images of `markdown`: `[text](target)`, `![alt](target)`.
fn link_targets(markdown: &str) -> Vec<String> {
    let text = prose(markdown);
    let mut targets = Vec::new();
    let mut rest = text.as_str();
    while let Some(at) = rest.find("](") {
        let after = &rest[at + 2..];
        let end = after.find(')').unwrap_or(after.len());
        targets.push(after[..end].trim().to_string());
        rest = &after[end..];
    }
    targets
}

/// The anchor GitHub gives a heading: lower case, letters, digits, `-` and `_` kept, spaces made `-`,
/// everything else (punctuation, backticks) dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of `markdown`'s headings (a repeated one gets `-1`, `-2` ... as on GitHub).
fn anchors(markdown: &str) -> HashSet<String> {
    let mut found = HashSet::new();
    let mut fenced = false;
    for line in markdown.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        let Some(heading) = line.strip_prefix('#').filter(|_| !fenced) else { continue };
        let heading = heading.trim_start_matches('#');
        if !heading.starts_with(' ') {
            continue;
        }
        let base = slug(heading);
        let mut anchor = base.clone();
        let mut n = 0;
        while found.contains(&anchor) {
            n += 1;
            anchor = format!("{base}-{n}");
        }
        found.insert(anchor);
    }
    found
}

/// Every relative link of the documentation names a file that exists, and every anchor a heading of
/// the page it names.
#[test]
fn every_doc_link_resolves() {
    let root = repo_root();
    let mut errors = Vec::new();
    let mut checked = 0;
    for page in pages() {
        let dir = root.join(&page.path).parent().unwrap().to_path_buf();
        for target in link_targets(&page.text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            checked += 1;
            let (path, anchor) = target.split_once('#').unwrap_or((&target, ""));
            let file = if path.is_empty() { root.join(&page.path) } else { dir.join(path) };
            if !file.exists() {
                errors.push(format!("{}: {target}: no file {}", page.path, file.display()));
                continue;
            }
            if !anchor.is_empty() {
                let text = std::fs::read_to_string(&file).unwrap_or_default();
                if !anchors(&text).contains(anchor) {
                    errors.push(format!("{}: {target}: no heading with the anchor #{anchor}", page.path));
                }
            }
        }
    }
    assert!(checked > 50, "{checked} links checked");
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

/// The link check finds what it should, and skips code.
#[test]
fn the_link_check_reads_markdown_as_github_does() {
    assert_eq!(slug("`move` succeeds only if the unit did it"), "move-succeeds-only-if-the-unit-did-it");
    assert_eq!(slug("`follow`: streamed setpoints"), "follow-streamed-setpoints");
    assert_eq!(slug("Results, errors and emulators"), "results-errors-and-emulators");
    let page = "# A\n## A\n```sh\n# not a heading\n```\nSee [b](b.md#x) and `[c](c.md)` and ``[d](d.md)``.\n\
                <!-- [e](e.md) -->![f](f.png)\n";
    assert_eq!(anchors(page), HashSet::from(["a".to_string(), "a-1".to_string()]));
    assert_eq!(link_targets(page), ["b.md#x", "f.png"]);
}
