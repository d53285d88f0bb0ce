//! Imports run one way (docs/design.md §1, the layout).
//!
//! - In every library crate's sources (the root package's `src/`, `core/`, `app/`, `hal-sim/`,
//!   `files/`, `link/`, `boards/*`): no file imports from a file that imports from it, directly or
//!   through others (a circle between files).
//! - In the root package's `src/`: no file imports from a layer above its own. The layers, top
//!   down: `cmd/`, `studies/`, then `machinery/` with `link_host/` beside it.
//!
//! What counts as file A importing from file B: a path in A's code, in a `use` or inline
//! (`crate::x::y`, `super::y`, `self::y`, or `child::y` for a child module of A's), whose longest
//! module prefix is B's module. Not counted: `#[cfg(test)]` modules and uses and the `tests.rs`
//! files (a test may look at anything), a module's `pub use` re-exports (a folder's facade), `mod`
//! declarations, comments, strings and macros at the crate root (`crate::outln!`).
//!
//! On failure every circle and every import that runs upward is printed, then the test fails.
//! `RTHS_LAYERS_ROOT=DIR` checks another checkout.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// A module path inside a crate: `["studies", "scenario"]` for `crate::studies::scenario`.
type ModPath = Vec<String>;

/// The repository root (`RTHS_LAYERS_ROOT=DIR`: another checkout, e.g. to count what `main` has).
fn root() -> PathBuf {
    std::env::var_os("RTHS_LAYERS_ROOT")
        .map_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")), PathBuf::from)
}

/// The text of Rust source `s` with its comments, string literals and char literals blanked
/// (lifetimes kept), so that only code is left to read paths from.
fn code_only(s: &str) -> String {
    let c: Vec<char> = s.chars().collect();
    let mut out = String::with_capacity(s.len());
    let mut i = 0;
    let at = |i: usize, pat: &str| {
        pat.chars()
            .enumerate()
            .all(|(k, p)| c.get(i + k) == Some(&p))
    };
    while i < c.len() {
        if at(i, "//") {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if at(i, "/*") {
            let mut depth = 0;
            while i < c.len() {
                if at(i, "/*") {
                    depth += 1;
                    i += 2;
                } else if at(i, "*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if (c[i] == 'r' || at(i, "br"))
            && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_'))
            && {
                let j = if c[i] == 'b' { i + 2 } else { i + 1 };
                let mut k = j;
                while c.get(k) == Some(&'#') {
                    k += 1;
                }
                c.get(k) == Some(&'"')
            }
        {
            // A raw string: r"…", r#"…"#, br"…".
            let j = if c[i] == 'b' { i + 2 } else { i + 1 };
            let mut hashes = 0;
            while c.get(j + hashes) == Some(&'#') {
                hashes += 1;
            }
            i = j + hashes + 1;
            loop {
                if i >= c.len() {
                    break;
                }
                if c[i] == '"' && (0..hashes).all(|h| c.get(i + 1 + h) == Some(&'#')) {
                    i += 1 + hashes;
                    break;
                }
                i += 1;
            }
            out.push_str("\"\"");
        } else if c[i] == '"' {
            i += 1;
            while i < c.len() && c[i] != '"' {
                i += if c[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if c[i] == '\'' {
            // A char literal ('x', '\n', '\u{..}'), else a lifetime ('a), kept.
            if c.get(i + 1) == Some(&'\\') {
                let mut k = i + 2;
                while k < c.len() && c[k] != '\'' {
                    k += 1;
                }
                i = k + 1;
                out.push_str("' '");
            } else if c.get(i + 2) == Some(&'\'') {
                i += 3;
                out.push_str("' '");
            } else {
                out.push(c[i]);
                i += 1;
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// The end (exclusive) of the item starting at `from`: through its matching `}` if a `{` comes
/// before the first `;`, else through that `;`.
fn item_end(s: &str, from: usize) -> usize {
    let b = s.as_bytes();
    let mut i = from;
    while i < b.len() {
        match b[i] {
            b';' => return i + 1,
            b'{' => {
                let mut depth = 0;
                while i < b.len() {
                    match b[i] {
                        b'{' => depth += 1,
                        b'}' => {
                            depth -= 1;
                            if depth == 0 {
                                return i + 1;
                            }
                        }
                        _ => {}
                    }
                    i += 1;
                }
                return b.len();
            }
            _ => i += 1,
        }
    }
    b.len()
}

/// `s` without its `#[cfg(test)]` items and its `pub use` re-exports.
fn non_test_non_reexport(s: &str) -> String {
    let mut s = s.to_string();
    while let Some(i) = s.find("#[cfg(test)]") {
        let end = item_end(&s, i);
        s.replace_range(i..end, " ");
    }
    let mut out = String::with_capacity(s.len());
    let mut rest = s.as_str();
    while let Some(i) = find_word(rest, "pub") {
        let after = rest[i + 3..].trim_start();
        let after = if after.starts_with('(') {
            after
                .find(')')
                .map_or(after, |j| after[j + 1..].trim_start())
        } else {
            after
        };
        if after.starts_with("use") && !after[3..].starts_with(|c: char| c.is_alphanumeric()) {
            out.push_str(&rest[..i]);
            let end = rest[i..].find(';').map_or(rest.len(), |j| i + j + 1);
            rest = &rest[end..];
        } else {
            out.push_str(&rest[..i + 3]);
            rest = &rest[i + 3..];
        }
    }
    out.push_str(rest);
    out
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The byte index of `word` in `s` as a whole word.
fn find_word(s: &str, word: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(j) = s[from..].find(word) {
        let i = from + j;
        let before = s[..i].chars().next_back().is_none_or(|c| !is_ident(c));
        let after = s[i + word.len()..]
            .chars()
            .next()
            .is_none_or(|c| !is_ident(c));
        if before && after {
            return Some(i);
        }
        from = i + word.len();
    }
    None
}

/// The paths of a `use` tree (`a::{b, c::{d, e as f}}` gives `a::b`, `a::c::d`, `a::c::e`).
fn use_paths(tree: &str, prefix: &str, out: &mut Vec<String>) {
    let t = tree.trim();
    if t.is_empty() {
        return;
    }
    if let (Some(open), true) = (t.find('{'), t.ends_with('}')) {
        let pre = t[..open].trim().trim_end_matches("::");
        let joined = match (prefix.is_empty(), pre.is_empty()) {
            (true, _) => pre.to_string(),
            (false, true) => prefix.to_string(),
            (false, false) => format!("{prefix}::{pre}"),
        };
        let inner = &t[open + 1..t.len() - 1];
        let mut depth = 0;
        let mut start = 0;
        for (k, ch) in inner.char_indices() {
            match ch {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    use_paths(&inner[start..k], &joined, out);
                    start = k + 1;
                }
                _ => {}
            }
        }
        use_paths(&inner[start..], &joined, out);
    } else {
        let name = t.split(" as ").next().unwrap_or(t).trim();
        out.push(if prefix.is_empty() {
            name.to_string()
        } else {
            format!("{prefix}::{name}")
        });
    }
}

/// Every path `code` names: its `use` trees and its inline `a::b` paths.
fn paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = code;
    // The code outside the `use` statements, for the inline paths.
    let mut inline = String::with_capacity(code.len());
    while let Some(i) = find_word(rest, "use") {
        let end = rest[i..].find(';').map_or(rest.len(), |j| i + j);
        use_paths(&rest[i + 3..end], "", &mut out);
        inline.push_str(&rest[..i]);
        rest = &rest[end..];
    }
    inline.push_str(rest);
    // Inline paths: identifiers joined by `::`.
    let c: Vec<char> = inline.chars().collect();
    let mut i = 0;
    while i < c.len() {
        if is_ident(c[i]) && (i == 0 || !(is_ident(c[i - 1]) || c[i - 1] == ':')) {
            let mut j = i;
            let mut segs = 1;
            loop {
                while j < c.len() && is_ident(c[j]) {
                    j += 1;
                }
                if c.get(j) == Some(&':')
                    && c.get(j + 1) == Some(&':')
                    && c.get(j + 2).is_some_and(|&x| is_ident(x))
                {
                    j += 2;
                    segs += 1;
                } else {
                    break;
                }
            }
            if segs > 1 {
                out.push(c[i..j].iter().collect());
            }
            i = j.max(i + 1);
        } else {
            i += 1;
        }
    }
    out
}

/// A crate's source files by module path (`tests.rs` files left out).
fn modules(src: &Path) -> BTreeMap<ModPath, PathBuf> {
    fn walk(dir: &Path, src: &Path, out: &mut BTreeMap<ModPath, PathBuf>) {
        let Ok(entries) = fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, src, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let rel = p.strip_prefix(src).unwrap_or(&p);
                let mut m: ModPath = rel
                    .with_extension("")
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                let last = m.last().cloned().unwrap_or_default();
                if last == "tests" || (m.len() == 1 && last == "main") {
                    continue;
                }
                if last == "mod" || (m.len() == 1 && last == "lib") {
                    m.pop();
                }
                out.insert(m, p);
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(src, src, &mut out);
    out
}

/// The file-level import graph of the crate whose sources are `src`.
fn graph(
    src: &Path,
) -> (
    BTreeMap<ModPath, PathBuf>,
    BTreeMap<ModPath, BTreeSet<ModPath>>,
) {
    let mods = modules(src);
    let mut g: BTreeMap<ModPath, BTreeSet<ModPath>> = BTreeMap::new();
    for (m, file) in &mods {
        let text = fs::read_to_string(file).unwrap_or_default();
        let code = non_test_non_reexport(&code_only(&text));
        let mut edges = BTreeSet::new();
        for p in paths(&code) {
            let segs: Vec<&str> = p.split("::").filter(|s| !s.is_empty()).collect();
            let Some(first) = segs.first() else { continue };
            let mut base: ModPath = match *first {
                "crate" => Vec::new(),
                "super" | "self" => m.clone(),
                name if mods.contains_key(&[m.clone(), vec![name.to_string()]].concat()) => {
                    m.clone()
                }
                _ => continue,
            };
            let mut rest = &segs[..];
            if *first == "crate" {
                rest = &segs[1..];
            } else {
                while let Some(s) = rest.first() {
                    match *s {
                        "super" => {
                            base.pop();
                        }
                        "self" => {}
                        _ => break,
                    }
                    rest = &rest[1..];
                }
            }
            let full: ModPath = base
                .into_iter()
                .chain(rest.iter().map(|s| s.to_string()))
                .collect();
            let target = (0..=full.len())
                .rev()
                .map(|k| full[..k].to_vec())
                .find(|k| mods.contains_key(k));
            if let Some(t) = target {
                // The crate root (its macros, its declarations) is no file's layer.
                if &t != m && !t.is_empty() {
                    edges.insert(t);
                }
            }
        }
        g.insert(m.clone(), edges);
    }
    (mods, g)
}

/// The circles of `g`: its strongly connected components of more than one module (Tarjan).
fn circles(g: &BTreeMap<ModPath, BTreeSet<ModPath>>) -> Vec<Vec<ModPath>> {
    struct T<'a> {
        g: &'a BTreeMap<ModPath, BTreeSet<ModPath>>,
        index: BTreeMap<ModPath, usize>,
        low: BTreeMap<ModPath, usize>,
        stack: Vec<ModPath>,
        on: BTreeSet<ModPath>,
        next: usize,
        out: Vec<Vec<ModPath>>,
    }
    fn visit(t: &mut T<'_>, v: &ModPath) {
        t.index.insert(v.clone(), t.next);
        t.low.insert(v.clone(), t.next);
        t.next += 1;
        t.stack.push(v.clone());
        t.on.insert(v.clone());
        let succ: Vec<ModPath> =
            t.g.get(v)
                .map(|s| s.iter().cloned().collect())
                .unwrap_or_default();
        for w in succ {
            if !t.index.contains_key(&w) {
                visit(t, &w);
                let lw = t.low[&w];
                let lv = t.low[v];
                t.low.insert(v.clone(), lv.min(lw));
            } else if t.on.contains(&w) {
                let iw = t.index[&w];
                let lv = t.low[v];
                t.low.insert(v.clone(), lv.min(iw));
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(&w);
                let done = &w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in g.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

/// The library crates' source directories.
fn crate_sources() -> Vec<PathBuf> {
    let r = root();
    let mut dirs: Vec<PathBuf> = [
        "src",
        "core/src",
        "app/src",
        "hal-sim/src",
        "files/src",
        "link/src",
    ]
    .iter()
    .map(|d| r.join(d))
    .collect();
    if let Ok(boards) = fs::read_dir(r.join("boards")) {
        let mut b: Vec<PathBuf> = boards
            .flatten()
            .map(|e| e.path().join("src"))
            .filter(|p| p.join("lib.rs").is_file())
            .collect();
        b.sort();
        dirs.extend(b);
    }
    dirs
}

fn shown(mods: &BTreeMap<ModPath, PathBuf>, m: &ModPath) -> String {
    mods.get(m)
        .and_then(|p| p.strip_prefix(root()).ok())
        .map_or_else(|| m.join("::"), |p| p.display().to_string())
}

#[test]
fn no_file_imports_from_a_file_that_imports_from_it() {
    let mut found = Vec::new();
    for src in crate_sources() {
        let (mods, g) = graph(&src);
        for comp in circles(&g) {
            let mut line = String::from("circle:");
            for m in &comp {
                line.push(' ');
                line.push_str(&shown(&mods, m));
            }
            for a in &comp {
                for b in g.get(a).into_iter().flatten().filter(|b| comp.contains(b)) {
                    line.push_str(&format!("\n    {} -> {}", shown(&mods, a), shown(&mods, b)));
                }
            }
            found.push(line);
        }
    }
    for f in &found {
        println!("{f}");
    }
    assert!(found.is_empty(), "{} circle(s) between files", found.len());
}

/// The layer of a root-package module: cmd 2, studies 1, machinery and link_host 0.
fn layer(m: &ModPath) -> Option<u8> {
    match m.first().map(String::as_str) {
        Some("cmd") => Some(2),
        Some("studies") => Some(1),
        Some("machinery" | "link_host") => Some(0),
        _ => None,
    }
}

#[test]
fn in_the_root_package_no_file_imports_from_a_layer_above_its_own() {
    let (mods, g) = graph(&root().join("src"));
    // The reader must see the imports it judges: a graph without these would pass anything.
    let edges: usize = g.values().map(BTreeSet::len).sum();
    assert!(edges > 300, "only {edges} imports found in src/");
    let known = |a: &[&str], b: &[&str]| {
        let a: ModPath = a.iter().map(|s| s.to_string()).collect();
        let b: ModPath = b.iter().map(|s| s.to_string()).collect();
        g.get(&a).is_some_and(|s| s.contains(&b))
    };
    assert!(known(&["studies", "scenario"], &["machinery", "drive"]));
    assert!(known(&["cmd", "simulate"], &["studies", "scenario"]));
    assert!(known(
        &["machinery", "train", "pure"],
        &["machinery", "drive"]
    ));
    let mut up = Vec::new();
    for (a, bs) in &g {
        for b in bs {
            if let (Some(la), Some(lb)) = (layer(a), layer(b)) {
                if lb > la {
                    up.push(format!("{} -> {}", shown(&mods, a), shown(&mods, b)));
                }
            }
        }
    }
    for u in &up {
        println!("upward: {u}");
    }
    assert!(up.is_empty(), "{} import(s) run upward", up.len());
}

/// The reader on a made-up file: comments, strings and test code are not imports; re-exports are
/// not either; `use` trees and inline paths are.
#[test]
fn the_reader_sees_imports_and_only_imports() {
    let text = r#"
        // use crate::commented::Away;
        use crate::a::{b::{C, D as E}, f};
        pub use crate::facade::Item;
        pub(crate) use crate::facade2::Item;
        fn g() { let s = "crate::in_string::X"; crate::inline::h(super::up::I); child::k(); }
        #[cfg(test)]
        mod tests { use crate::test_only::T; }
    "#;
    let code = non_test_non_reexport(&code_only(text));
    let mut p = paths(&code);
    p.sort();
    assert_eq!(
        p,
        [
            "child::k",
            "crate::a::b::C",
            "crate::a::b::D",
            "crate::a::f",
            "crate::inline::h",
            "super::up::I"
        ]
    );
}
