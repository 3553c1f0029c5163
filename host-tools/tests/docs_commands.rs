//! The README's and `docs/`'s examples, run: every fenced `console` block's `$ ` commands
//! are run in a scratch folder (one per page, blocks in page order, so a page can slice
//! and then simulate what it sliced) with this build's `dollop` first on `PATH`, and each
//! line of output the page shows must appear in what the command printed, in order
//! (`[..]` in a shown line stands for any text, a `...` line for lines left out). A block
//! line `[exit N]` expects that exit code; otherwise 0. Also: every relative link in these
//! pages resolves inside the repository, and the README stays a front door (under 250
//! lines). Where it stops: `sh` blocks are shown, not run (the dashboard, the board, the
//! emulator and the test suite itself have their own tests).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The repository's root (the parent of the host-tools package).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The pages: README.md, then docs/*.md by name.
fn pages() -> Vec<PathBuf> {
    let mut docs: Vec<PathBuf> = fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    let mut all = vec![root().join("README.md")];
    all.extend(docs);
    all
}

/// One `$ ` command of a console block and the output the page shows for it.
#[derive(Debug)]
struct Example {
    line: usize,
    command: String,
    shown: Vec<String>,
    exit: i32,
}

/// The console blocks' commands of a page, in order.
fn examples(text: &str) -> Vec<Example> {
    let mut out: Vec<Example> = Vec::new();
    let mut in_console = false;
    let mut in_fence = false;
    let mut continued = false;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("```") {
            if in_fence {
                in_fence = false;
                in_console = false;
            } else {
                in_fence = true;
                in_console = trimmed.trim_start_matches('`').trim() == "console";
            }
            continue;
        }
        if !in_console {
            continue;
        }
        if continued {
            let ex = out.last_mut().unwrap();
            ex.command.push('\n');
            ex.command.push_str(line);
            continued = line.ends_with('\\');
        } else if let Some(cmd) = line.strip_prefix("$ ") {
            out.push(Example {
                line: i + 1,
                command: cmd.to_string(),
                shown: Vec::new(),
                exit: 0,
            });
            continued = cmd.ends_with('\\');
        } else if let Some(ex) = out.last_mut() {
            if let Some(code) = line
                .strip_prefix("[exit ")
                .and_then(|r| r.strip_suffix(']'))
            {
                ex.exit = code.trim().parse().expect("[exit N] takes a number");
            } else if !line.trim().is_empty() && line.trim() != "..." {
                ex.shown.push(line.trim_end().to_string());
            }
        }
    }
    out
}

/// Whether `actual` matches the shown line `pattern`, `[..]` standing for any text.
fn matches(pattern: &str, actual: &str) -> bool {
    let parts: Vec<&str> = pattern.split("[..]").collect();
    if parts.len() == 1 {
        return pattern == actual.trim_end();
    }
    let actual = actual.trim_end();
    let mut rest = actual;
    for (k, part) in parts.iter().enumerate() {
        if k == 0 {
            match rest.strip_prefix(part) {
                Some(r) => rest = r,
                None => return false,
            }
        } else if k == parts.len() - 1 {
            return rest.ends_with(part);
        } else {
            match rest.find(part) {
                Some(at) => rest = &rest[at + part.len()..],
                None => return false,
            }
        }
    }
    true
}

/// The first shown line not found, in order, in `printed`.
fn first_missing<'a>(shown: &'a [String], printed: &str) -> Option<&'a str> {
    let mut lines = printed.lines();
    'shown: for want in shown {
        for got in lines.by_ref() {
            if matches(want, got) {
                continue 'shown;
            }
        }
        return Some(want);
    }
    None
}

/// A fresh scratch folder for `page`, with the repository's inputs linked in.
fn scratch(page: &Path) -> PathBuf {
    let stem = page.file_stem().unwrap().to_string_lossy().to_string();
    let dir = root().join("target/tmp/docs").join(stem);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    for name in ["configs", "host-tools", "docs", "sim", "tests"] {
        std::os::unix::fs::symlink(root().join(name), dir.join(name)).unwrap();
    }
    dir
}

#[test]
fn the_pages_console_examples_print_what_the_pages_show() {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_dollop")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut failures = Vec::new();
    let mut ran = 0;
    for page in pages() {
        let text = fs::read_to_string(&page).unwrap();
        let examples = examples(&text);
        if examples.is_empty() {
            continue;
        }
        let dir = scratch(&page);
        let name = page.strip_prefix(root()).unwrap().display().to_string();
        for ex in &examples {
            let out = Command::new("sh")
                .arg("-c")
                .arg(format!("exec 2>&1\n{}", ex.command))
                .current_dir(&dir)
                .env("PATH", &path)
                .env("NO_COLOR", "1")
                .stdin(Stdio::null())
                .output()
                .unwrap();
            ran += 1;
            let printed = String::from_utf8_lossy(&out.stdout);
            let code = out.status.code().unwrap_or(-1);
            eprintln!("{name}:{}: $ {} -> exit {code}", ex.line, ex.command);
            if code != ex.exit {
                failures.push(format!(
                    "{name}:{}: `{}` exited {code}, the page expects {}; it printed:\n{printed}",
                    ex.line, ex.command, ex.exit
                ));
            } else if let Some(want) = first_missing(&ex.shown, &printed) {
                failures.push(format!(
                    "{name}:{}: `{}` did not print (in the page's order) the line\n  {want}\nit printed:\n{printed}",
                    ex.line, ex.command
                ));
            }
        }
    }
    eprintln!("{ran} commands run");
    assert!(ran > 0, "no console examples found");
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_relative_link_resolves_inside_the_repository() {
    let mut broken = Vec::new();
    for page in pages() {
        let text = fs::read_to_string(&page).unwrap();
        let base = page.parent().unwrap();
        let mut in_fence = false;
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("```") {
                in_fence = !in_fence;
                continue;
            }
            if in_fence {
                continue;
            }
            let mut rest = line;
            while let Some(at) = rest.find("](") {
                let after = &rest[at + 2..];
                let Some(end) = after.find(')') else { break };
                let target = &after[..end];
                rest = &after[end..];
                if target.contains("://")
                    || target.starts_with('#')
                    || target.starts_with("mailto:")
                {
                    continue;
                }
                let file = target.split('#').next().unwrap();
                let resolved = base.join(file);
                let inside = resolved
                    .canonicalize()
                    .map(|p| p.starts_with(root().canonicalize().unwrap()))
                    .unwrap_or(false);
                if !inside {
                    broken.push(format!(
                        "{}:{}: {target}",
                        page.strip_prefix(root()).unwrap().display(),
                        i + 1
                    ));
                }
            }
        }
    }
    assert!(
        broken.is_empty(),
        "links that do not resolve inside the repository:\n{}",
        broken.join("\n")
    );
}

#[test]
fn the_readme_is_a_front_door() {
    let text = fs::read_to_string(root().join("README.md")).unwrap();
    let lines = text.lines().count();
    assert!(
        lines < 250,
        "README.md has {lines} lines: the detail belongs in docs/"
    );
    assert!(
        text.contains("docs/README.md"),
        "README.md must point at the docs index"
    );
}

#[test]
fn the_runner_matches_what_it_should() {
    assert!(matches("wrote a.png", "wrote a.png  "));
    assert!(matches("took [..] s, [..] lines", "took 1.5 s, 20 lines"));
    assert!(!matches("took [..] s", "took 1.5 ms!"));
    assert!(!matches("wrote a.png", "wrote b.png"));
    let shown = vec!["a".to_string(), "c".to_string()];
    assert_eq!(first_missing(&shown, "a\nb\nc\n"), None);
    assert_eq!(first_missing(&shown, "c\na\n"), Some("c"));
    let ex = examples("```console\n$ dollop x \\\n  --y\nout\n[exit 2]\n```\n```sh\n$ no\n```\n");
    assert_eq!(ex.len(), 1);
    assert_eq!(ex[0].command, "dollop x \\\n  --y");
    assert_eq!(ex[0].shown, vec!["out".to_string()]);
    assert_eq!(ex[0].exit, 2);
}
