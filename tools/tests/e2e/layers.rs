//! The floors of tools/src (docs/DESIGN.md "The floors of tools/src"): no module imports one
//! above it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The floors as DESIGN.md lists them: module -> (floor, place on the floor).
fn floors() -> BTreeMap<String, (usize, usize)> {
    let design = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/DESIGN.md");
    let text = std::fs::read_to_string(&design).unwrap();
    let at = text
        .find("<!-- layers:")
        .expect("DESIGN.md lists the floors");
    let block = text[at..].split("```text\n").nth(1).unwrap();
    let block = &block[..block.find("```").unwrap()];
    let mut out = BTreeMap::new();
    for line in block.lines().filter(|l| !l.trim().is_empty()) {
        let (head, modules) = line.split_once(':').expect("`N name: modules`");
        let floor: usize = head.split_whitespace().next().unwrap().parse().unwrap();
        for (i, m) in modules.split_whitespace().enumerate() {
            assert!(
                out.insert(m.to_string(), (floor, i)).is_none(),
                "{m} listed twice"
            );
        }
    }
    out
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The top-level modules a source names through `crate::` (comments left out; `crate::{a,
/// b::c}` names a and b; the crate root's `Error` and `ErrorKind` are `error`'s).
fn imports(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in code.lines() {
        let line = line.split("//").next().unwrap();
        let mut rest = line;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                // Names at the group's top level (before `::`, `,` or `}` at depth 0).
                let (mut depth, mut start, mut names) = (0, true, Vec::new());
                let mut name = String::new();
                for c in group.chars() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => {
                            if !name.is_empty() {
                                names.push(std::mem::take(&mut name));
                            }
                            start = true;
                        }
                        c if start && depth == 0 && (c.is_alphanumeric() || c == '_') => {
                            name.push(c)
                        }
                        _ if start && !name.is_empty() => {
                            names.push(std::mem::take(&mut name));
                            start = false;
                        }
                        _ => {}
                    }
                }
                if !name.is_empty() {
                    names.push(name);
                }
                out.extend(names);
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                out.push(name);
            }
        }
    }
    out.into_iter()
        .filter(|n| !n.is_empty() && n != "self")
        .map(|n| match n.as_str() {
            "Error" | "ErrorKind" => "error".to_string(),
            _ => n,
        })
        .collect()
}

/// No `use crate::` in tools/src runs uphill: a module imports modules of lower floors, or of
/// its own floor listed before it; every module is on a floor.
#[test]
fn tools_src_imports_never_run_uphill() {
    let floors = floors();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    files.sort();
    let mut wrong = Vec::new();
    let mut edges = 0;
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        let top = rel.iter().next().unwrap().to_string_lossy();
        let top = top.trim_end_matches(".rs").to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let Some(&from) = floors.get(&top) else {
            wrong.push(format!(
                "{}: module {top} is on no floor of DESIGN.md",
                rel.display()
            ));
            continue;
        };
        for to in imports(&std::fs::read_to_string(f).unwrap()) {
            if to == top {
                continue;
            }
            edges += 1;
            match floors.get(&to) {
                None => wrong.push(format!("{}: crate::{to} is on no floor", rel.display())),
                Some(&t) if t >= from => wrong.push(format!(
                    "{}: {top} (floor {}) imports {to} (floor {}): uphill",
                    rel.display(),
                    from.0,
                    t.0
                )),
                Some(_) => {}
            }
        }
    }
    assert!(edges > 200, "{edges} imports found: the reader misses them");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The reader finds what it must.
#[test]
fn the_import_reader_sees_groups_and_paths() {
    let code = "use crate::config::site::Site; // crate::rig in a comment\n\
                use crate::{calibrate, report::{Report, Sigma}, session::scratch::Scratch};\n\
                fn f() -> crate::Error { crate::plan::bound(1.0) }";
    assert_eq!(
        imports(code),
        ["config", "calibrate", "report", "session", "error", "plan"]
    );
}
