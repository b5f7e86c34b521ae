//! The sections of `benches/summary.md` that one bench owns: the text between the markers
//! `<!-- NAME: cargo bench --bench NAME -->` and `<!-- /NAME -->`. A bench rewrites its own and
//! keeps the others'; `cargo bench --bench step` writes the rest of the file and keeps them all.
// Each bench includes this module and uses part of it.
#![allow(dead_code)]

use std::path::PathBuf;

/// The benches that own a section, in the order the file lists them.
pub const OWNED: [&str; 3] = ["failure", "formulations", "wall"];

/// `benches/summary.md`.
pub fn path() -> PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/summary.md")
}

fn start(name: &str) -> String {
    format!("<!-- {name}: cargo bench --bench {name} -->")
}

fn end(name: &str) -> String {
    format!("<!-- /{name} -->")
}

/// The section `name` of `text`, markers included, if it has one.
pub fn find<'t>(text: &'t str, name: &str) -> Option<&'t str> {
    let (s, e) = (start(name), end(name));
    let a = text.find(&s)?;
    let b = text[a..].find(&e)? + a;
    Some(&text[a..b + e.len()])
}

/// Writes `body` as the section `name` of `benches/summary.md`, in place of the one there or
/// at the end; the rest of the file stays.
pub fn write(name: &str, body: &str) {
    let path = path();
    let old = std::fs::read_to_string(&path).unwrap_or_default();
    let section = format!("{}\n{}\n{}", start(name), body.trim_end(), end(name));
    let text = match find(&old, name) {
        Some(s) => old.replacen(s, &section, 1),
        None => format!("{}\n\n{section}\n", old.trim_end()),
    };
    std::fs::write(&path, text).expect("benches/summary.md is written");
    println!("wrote the section `{name}` of {}", path.display());
}

/// `summary` followed by the owned sections of the file as it is now.
pub fn keep_owned(summary: String) -> String {
    let old = std::fs::read_to_string(path()).unwrap_or_default();
    let mut out = summary.trim_end().to_string();
    for name in OWNED {
        if let Some(s) = find(&old, name) {
            out = format!("{out}\n\n{s}");
        }
    }
    out + "\n"
}
