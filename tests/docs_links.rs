//! Documentation that exists: every reference in the README, in `docs/` and in code comments must
//! resolve to something in the repository.
//!
//! Checked, in every `README.md` and in `docs/**/*.md` (whole text) and in the comments of `**/*.rs`,
//! `**/*.sh`, `**/*.toml` and `.ci/run` (`target/` and `.git` skipped):
//! - (a) relative Markdown links (a bracketed text, then the path and an optional `#anchor` in
//!   parentheses): the path exists, and an anchor into a Markdown file names one of its headings
//!   (GitHub's slug rules);
//! - (b) cited repository paths (`core/src/control.rs`, `docs/design.md`, `src/cmd/`): the path
//!   exists relative to the repository root, to the citing file's directory or one of its
//!   ancestors (so `src/lib.rs` inside `core/` resolves against its crate), or to the enclosing
//!   crate's `src/`;
//! - (c) section citations (a Markdown file, then `§N` or `§N.M`): the file has a heading `N.` /
//!   `N.M`;
//! - (d) citations of files that are not part of the repository: the original design brief (the
//!   word DESIGN followed by a section sign), the `shared` directory beside the repository, and
//!   the `notes` directory of Markdown files that never shipped.
//!
//! Every dangling reference is printed as `file:line: what`, then the test fails.
//! `RTHS_DOCS_ROOT=DIR` checks another checkout (e.g. to count what `main` has today).

use std::collections::HashSet;
use std::fmt;
use std::fs;
use std::path::{Component, Path, PathBuf};

/// Generated paths, which cannot exist in a checkout: build outputs (any `target` directory, the
/// build script's `$OUT_DIR`), what `rths reproduce` writes (`out/`) and cargo-fuzz's crash
/// inputs. Kept short on purpose: anything else that dangles is a real finding.
const GENERATED_PREFIXES: &[&str] = &["out/", "$OUT_DIR/", "OUT_DIR/", "fuzz/artifacts/"];

/// File extensions that make a token with a `/` a cited file path.
const PATH_EXTENSIONS: &[&str] = &[
    "rs", "md", "toml", "sh", "json", "at2", "csv", "png", "x", "lock", "yml", "yaml", "txt",
    "ttf", "py",
];

/// One dangling reference.
#[derive(Debug, Clone, PartialEq)]
struct Finding {
    file: String,
    line: usize,
    what: String,
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.what)
    }
}

/// How a file's text is scanned.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// Markdown: the whole text (code blocks too: a path in a command must exist as well).
    Markdown,
    /// Rust: `//` comments only.
    Rust,
    /// Shell, TOML: `#` comments only.
    Hash,
}

/// The repository being checked: its root and its top-level entries (a token whose first segment
/// is one of them is a repository path even without a file extension, e.g. `src/cmd/`).
struct Repo {
    root: PathBuf,
    top_level: HashSet<String>,
}

impl Repo {
    fn new(root: &Path) -> Repo {
        let top_level = fs::read_dir(root)
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| !n.starts_with('.') && n != "target")
                    .collect()
            })
            .unwrap_or_default();
        Repo {
            root: root.to_path_buf(),
            top_level,
        }
    }
}

/// Lexically normalizes `p` (no symlinks followed); `None` if it climbs above its start.
fn normalize(p: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::CurDir => {}
            other => out.push(other.as_os_str()),
        }
    }
    Some(out)
}

/// Candidate repository-relative locations of `cited`, as seen from the file `from` (itself
/// repository-relative): its directory and every ancestor up to the root, then the enclosing
/// crate's `src/`.
fn candidates(repo: &Repo, from: &Path, cited: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut dir = from.parent().map(Path::to_path_buf);
    while let Some(d) = dir {
        if let Some(p) = normalize(&d.join(cited)) {
            out.push(p);
        }
        if repo.root.join(&d).join("Cargo.toml").is_file() {
            if let Some(p) = normalize(&d.join("src").join(cited)) {
                out.push(p);
            }
        }
        dir = d.parent().map(Path::to_path_buf);
    }
    out
}

/// The repository-relative path `cited` resolves to, if any.
fn resolve(repo: &Repo, from: &Path, cited: &str) -> Option<PathBuf> {
    candidates(repo, from, cited)
        .into_iter()
        .find(|p| repo.root.join(p).exists())
}

/// GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .chars()
        .filter_map(|c| {
            if c == ' ' {
                Some('-')
            } else if c.is_alphanumeric() || c == '-' || c == '_' {
                Some(c)
            } else {
                None
            }
        })
        .flat_map(char::to_lowercase)
        .collect()
}

/// The Markdown headings of `text` (outside fenced code), as (level, text).
fn headings(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let level = line.chars().take_while(|&c| c == '#').count();
        if (1..=6).contains(&level) && line[level..].starts_with(' ') {
            out.push((level, line[level..].trim().to_string()));
        }
    }
    out
}

/// Every anchor a Markdown text offers (duplicates numbered as GitHub does).
fn anchors(text: &str) -> HashSet<String> {
    let mut seen = HashSet::new();
    for (_, h) in headings(text) {
        let base = slug(&h);
        let mut s = base.clone();
        let mut n = 1;
        while seen.contains(&s) {
            s = format!("{base}-{n}");
            n += 1;
        }
        seen.insert(s);
    }
    seen
}

/// Whether a Markdown text has a numbered section `N.` or `N.M` as a heading.
fn has_section(text: &str, section: &str) -> bool {
    headings(text).iter().any(|(_, h)| {
        h.strip_prefix(section)
            .is_some_and(|rest| rest.starts_with('.') || rest.starts_with(' '))
    })
}

/// The scanned part of each line: the whole line for Markdown, the comment for code.
fn scanned_lines(text: &str, kind: Kind) -> Vec<(usize, String)> {
    text.lines()
        .enumerate()
        .filter_map(|(i, line)| {
            let part = match kind {
                Kind::Markdown => Some(line),
                Kind::Rust => comment_after(line, "//"),
                Kind::Hash => {
                    if i == 0 && line.starts_with("#!") {
                        None
                    } else {
                        comment_after(line, "#")
                    }
                }
            };
            part.map(|p| (i + 1, p.to_string()))
        })
        .collect()
}

/// The text after the first `marker` outside a string literal (`"..."`) on this line.
fn comment_after<'a>(line: &'a str, marker: &str) -> Option<&'a str> {
    let mut in_str = false;
    let mut escaped = false;
    let mut prev = ' ';
    for (i, c) in line.char_indices() {
        if in_str {
            match c {
                _ if escaped => escaped = false,
                '\\' => escaped = true,
                '"' => in_str = false,
                _ => {}
            }
        } else if c == '"' {
            in_str = true;
        } else if line[i..].starts_with(marker) && !(marker == "//" && prev == ':') {
            // (`://` is a URL, not a comment.)
            return Some(&line[i + marker.len()..]);
        }
        prev = c;
    }
    None
}

/// Blanks out URLs so that their paths are not taken for repository paths.
fn strip_urls(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut rest = line;
    while let Some(pos) = rest.find("://") {
        let start = rest[..pos]
            .rfind(|c: char| !c.is_ascii_alphanumeric() && c != '+' && c != '.' && c != '-')
            .map_or(0, |p| p + 1);
        out.push_str(&rest[..start]);
        let after = &rest[pos + 3..];
        let end = after
            .find(|c: char| c.is_whitespace() || c == ')' || c == '>' || c == '`')
            .unwrap_or(after.len());
        out.push(' ');
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// The targets of the Markdown links on a line.
fn md_links(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(pos) = rest.find("](") {
        let after = &rest[pos + 2..];
        let end = after.find(')').unwrap_or(after.len());
        let target = after[..end].split_whitespace().next().unwrap_or("");
        out.push(target.to_string());
        rest = &after[end..];
    }
    out
}

/// Expands one level of `{a,b}` alternatives (`rnn-{5,10}.json` → `rnn-5.json`, `rnn-10.json`).
fn expand_braces(token: &str) -> Vec<String> {
    match (token.find('{'), token.find('}')) {
        (Some(a), Some(b)) if a < b => token[a + 1..b]
            .split(',')
            .flat_map(|alt| expand_braces(&format!("{}{}{}", &token[..a], alt, &token[b + 1..])))
            .collect(),
        _ => vec![token.to_string()],
    }
}

/// Tokens of a line that look like repository paths.
fn path_tokens(line: &str, repo: &Repo) -> Vec<String> {
    let is_path_char = |c: char| c.is_ascii_alphanumeric() || "_.-/${},".contains(c);
    let mut out = Vec::new();
    for raw in line.split(|c: char| !is_path_char(c)) {
        // A comma ends a word unless it sits inside `{..}`.
        let raw = if raw.contains('{') {
            raw
        } else {
            raw.split(',').next().unwrap_or("")
        };
        let token = raw.trim_end_matches(['.', ',']).trim_start_matches("./");
        if !token.contains('/') || token.starts_with('/') || token.contains("//") {
            continue;
        }
        for t in expand_braces(token) {
            if looks_like_repo_path(&t, repo) {
                out.push(t);
            }
        }
    }
    out
}

fn looks_like_repo_path(token: &str, repo: &Repo) -> bool {
    let first = token
        .trim_start_matches("../")
        .split('/')
        .next()
        .unwrap_or("");
    if first.is_empty() || generated(token) || placeholder(token) || forbidden_path(token) {
        return false;
    }
    // `DIR/report.md`, `OUT/x.csv`: a placeholder for a directory the user picks.
    if first.chars().all(|c| c.is_ascii_uppercase() || c == '_') {
        return false;
    }
    let name = token.rsplit('/').next().unwrap_or("");
    let has_ext = name
        .rsplit_once('.')
        .is_some_and(|(stem, ext)| !stem.is_empty() && PATH_EXTENSIONS.contains(&ext));
    has_ext || repo.top_level.contains(first)
}

fn generated(token: &str) -> bool {
    GENERATED_PREFIXES.iter().any(|p| token.starts_with(p))
        || token.split('/').any(|s| s == "target")
}

/// A placeholder the reader fills in: a one-letter capital segment or suffix (`docs/X.md`,
/// `data/models/rnn-H.json`, `H` standing for 5, 10 or 20).
fn placeholder(token: &str) -> bool {
    token.split('/').any(|seg| {
        let stem = seg.split('.').next().unwrap_or("");
        let last = stem.rsplit(['-', '_']).next().unwrap_or("");
        last.len() == 1 && last.chars().all(|c| c.is_ascii_uppercase())
    })
}

/// Checks one file's text; `rel` is its repository-relative path.
fn check_text(repo: &Repo, rel: &Path, text: &str, kind: Kind) -> Vec<Finding> {
    let mut out = Vec::new();
    let file = rel.to_string_lossy().into_owned();
    let mut push = |line: usize, what: String| {
        out.push(Finding {
            file: file.clone(),
            line,
            what,
        })
    };
    let own_anchors = (kind == Kind::Markdown).then(|| anchors(text));
    for (n, line) in scanned_lines(text, kind) {
        let line = strip_urls(&line);
        // (d) references to files outside the repository.
        for bad in forbidden(&line) {
            push(
                n,
                format!("cites `{bad}`, which is not part of the repository"),
            );
        }
        // (a) Markdown links.
        let links = md_links(&line);
        for target in &links {
            if target.is_empty() || target.starts_with("mailto:") || target.contains("::") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            if path.is_empty() {
                if let (Some(a), Some(own)) = (anchor, &own_anchors) {
                    if !own.contains(a) {
                        push(n, format!("link to `#{a}`: no such heading in this file"));
                    }
                }
                continue;
            }
            if generated(path) {
                continue;
            }
            let Some(dir) = rel.parent() else { continue };
            let Some(p) = normalize(&dir.join(path)) else {
                push(n, format!("link `{target}` leaves the repository"));
                continue;
            };
            let full = repo.root.join(&p);
            if !full.exists() {
                push(
                    n,
                    format!("link `{target}`: {} does not exist", p.display()),
                );
                continue;
            }
            if let Some(a) = anchor {
                if path.ends_with(".md") {
                    let t = fs::read_to_string(&full).unwrap_or_default();
                    if !anchors(&t).contains(a) {
                        push(
                            n,
                            format!("link `{target}`: no heading `#{a}` in {}", p.display()),
                        );
                    }
                }
            }
        }
        // (b) cited paths; link targets were checked above (relative to the file only).
        let link_targets: HashSet<&str> = links.iter().map(String::as_str).collect();
        for token in path_tokens(&line, repo) {
            if link_targets.iter().any(|t| t.starts_with(token.as_str())) {
                continue;
            }
            if resolve(repo, rel, &token).is_none() {
                push(n, format!("cites `{token}`, which does not exist"));
            }
        }
        // (c) section citations `X.md §N`.
        for (doc, section) in section_citations(&line) {
            match resolve(repo, rel, &doc) {
                None => push(n, format!("cites `{doc} §{section}`: no such file")),
                Some(p) => {
                    let t = fs::read_to_string(repo.root.join(&p)).unwrap_or_default();
                    if !has_section(&t, &section) {
                        push(
                            n,
                            format!("cites `{doc} §{section}`: no heading `{section}.` there"),
                        );
                    }
                }
            }
        }
    }
    out
}

/// A path that (d) reports already: not checked again as a path.
fn forbidden_path(token: &str) -> bool {
    token.contains(SHARED) || (token.starts_with(NOTES) && token.ends_with(".md"))
}

/// The directory beside the repository that held the design brief and the working notes.
const SHARED: &str = concat!("shared", "/");
/// The notes directory that never shipped.
const NOTES: &str = concat!("notes", "/");

/// (d): the design brief, the `shared` directory and the `notes` Markdown files.
fn forbidden(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let brief = concat!("DESIGN", " §");
    if line.contains(brief) {
        out.push(brief.to_string());
    }
    let parent_shared = format!("../{SHARED}");
    let brief_file = format!("{SHARED}DESIGN.md");
    if line.contains(&parent_shared) {
        out.push(parent_shared);
    } else if line.contains(&brief_file) {
        out.push(brief_file);
    }
    let mut rest = line;
    let notes = NOTES;
    while let Some(pos) = rest.find(notes) {
        let before_ok = pos == 0 || !rest.as_bytes()[pos - 1].is_ascii_alphanumeric();
        let after = &rest[pos + notes.len()..];
        let name: String = after
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || "_-.*".contains(*c))
            .collect();
        if before_ok && name.ends_with(".md") {
            out.push(format!("{notes}{name}"));
        }
        rest = after;
    }
    out
}

/// `(file, section)` for every `X.md §N` / `X.md §N.M` on a line (a link's text included).
fn section_citations(line: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(pos) = rest.find(".md §") {
        let head = &rest[..pos];
        let start = head
            .rfind(|c: char| !(c.is_ascii_alphanumeric() || "_./-".contains(c)))
            .map_or(0, |p| p + 1);
        let after = &rest[pos + ".md §".len()..];
        let mut section: String = after
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.')
            .collect();
        while section.ends_with('.') {
            section.pop();
        }
        if start < pos && !section.is_empty() {
            out.push((format!("{}.md", &head[start..]), section));
        }
        rest = after;
    }
    out
}

/// The files to scan: every `README.md`, `docs/**/*.md`, and code, scripts and manifests.
fn files(root: &Path) -> Vec<(PathBuf, Kind)> {
    let mut out = vec![(PathBuf::from("README.md"), Kind::Markdown)];
    if root.join(".ci/run").is_file() {
        out.push((PathBuf::from(".ci/run"), Kind::Hash));
    }
    let mut stack = vec![PathBuf::new()];
    while let Some(dir) = stack.pop() {
        let Ok(rd) = fs::read_dir(root.join(&dir)) else {
            continue;
        };
        for entry in rd.filter_map(|e| e.ok()) {
            let name = entry.file_name().to_string_lossy().into_owned();
            let rel = dir.join(&name);
            let Ok(ft) = entry.file_type() else { continue };
            if ft.is_dir() {
                if name != "target" && name != ".git" {
                    stack.push(rel);
                }
                continue;
            }
            let kind = match rel.extension().and_then(|e| e.to_str()) {
                Some("rs") => Kind::Rust,
                Some("sh") | Some("toml") => Kind::Hash,
                // The root README is first above; every other README (firmware, boards, data) too.
                Some("md")
                    if rel.starts_with("docs") || (name == "README.md" && dir != Path::new("")) =>
                {
                    Kind::Markdown
                }
                _ => continue,
            };
            out.push((rel, kind));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// Checks the whole repository at `root`.
fn check_repo(root: &Path) -> Vec<Finding> {
    let repo = Repo::new(root);
    files(root)
        .into_iter()
        .flat_map(|(rel, kind)| match fs::read_to_string(root.join(&rel)) {
            Ok(text) => check_text(&repo, &rel, &text, kind),
            Err(e) => vec![Finding {
                file: rel.to_string_lossy().into_owned(),
                line: 0,
                what: format!("cannot read: {e}"),
            }],
        })
        .collect()
}

#[test]
fn every_reference_in_readme_docs_and_comments_resolves() {
    let root = std::env::var_os("RTHS_DOCS_ROOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    let findings = check_repo(&root);
    for f in &findings {
        eprintln!("{f}");
    }
    eprintln!(
        "{} dangling reference(s) in {}",
        findings.len(),
        root.display()
    );
    assert!(
        findings.is_empty(),
        "{} dangling reference(s); listed above",
        findings.len()
    );
}

#[cfg(test)]
mod extractor {
    use super::*;

    /// A small repository in a temporary directory.
    fn repo() -> (tempfile::TempDir, Repo) {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for (p, text) in [
            ("Cargo.toml", "[package]\n"),
            ("src/lib.rs", "//! lib\n"),
            ("core/Cargo.toml", "[package]\n"),
            ("core/src/lib.rs", "//! core\n"),
            ("core/src/control.rs", "//! control\n"),
            (
                "docs/design.md",
                "# Design\n## 1. Layout\n### 1.2 Crates\n## 4. Specimen scale and the plant\n",
            ),
            (
                "docs/plant.md",
                "# Plant\n## Model (`hal-sim`)\n## Model (`hal-sim`)\n",
            ),
        ] {
            let path = root.join(p);
            fs::create_dir_all(path.parent().unwrap()).unwrap();
            fs::write(path, text).unwrap();
        }
        let repo = Repo::new(root);
        (dir, repo)
    }

    fn md(repo: &Repo, text: &str) -> Vec<Finding> {
        check_text(repo, Path::new("docs/x.md"), text, Kind::Markdown)
    }

    #[test]
    fn slugs_follow_github() {
        assert_eq!(
            slug("4. Specimen scale and the plant"),
            "4-specimen-scale-and-the-plant"
        );
        assert_eq!(slug("Model (`hal-sim`)"), "model-hal-sim");
        assert_eq!(
            slug("Measured figures (QEMU 7.2, Rust 1.95, opt-level 3, fat LTO)"),
            "measured-figures-qemu-72-rust-195-opt-level-3-fat-lto"
        );
        let a = anchors("## Model (`hal-sim`)\n## Model (`hal-sim`)\n```\n# not a heading\n```\n");
        assert!(a.contains("model-hal-sim") && a.contains("model-hal-sim-1"));
        assert!(!a.contains("not-a-heading"));
    }

    #[test]
    fn a_dangling_link_is_caught() {
        let (_d, repo) = repo();
        let f = md(&repo, "See [the plant](plan.md) and [design](design.md).\n");
        assert_eq!(f.len(), 1, "{f:?}");
        assert_eq!(f[0].line, 1);
        assert!(f[0].what.contains("plan.md"), "{f:?}");
    }

    #[test]
    fn anchors_are_checked_in_other_files_and_this_one() {
        let (_d, repo) = repo();
        let ok = "[a](design.md#4-specimen-scale-and-the-plant) [b](plant.md#model-hal-sim-1)\n\
                  ## Here\n[c](#here)\n";
        assert_eq!(md(&repo, ok), vec![]);
        let bad = "[a](design.md#4-specimen-scale) [c](#nowhere)\n";
        assert_eq!(md(&repo, bad).len(), 2);
    }

    #[test]
    fn cited_paths_resolve_from_root_file_and_crate() {
        let (_d, repo) = repo();
        // From the root, from `docs/`, and crate-relative inside `core/`.
        assert_eq!(
            md(&repo, "`core/src/control.rs`, `docs/plant.md`, `src/`\n"),
            vec![]
        );
        let rs =
            "//! See `src/control.rs` and `core/src/lib.rs`; speed in mm/s.\nlet a = \"x/y.rs\";\n";
        assert_eq!(
            check_text(&repo, Path::new("core/src/lib.rs"), rs, Kind::Rust),
            vec![]
        );
        let f = check_text(
            &repo,
            Path::new("core/src/lib.rs"),
            "// see `src/gone.rs`\n",
            Kind::Rust,
        );
        assert_eq!(f.len(), 1, "{f:?}");
        let f = md(&repo, "`core/src/metamodel.rs` and `core/src/nothing/`\n");
        assert_eq!(f.len(), 2, "{f:?}");
    }

    #[test]
    fn generated_paths_urls_and_placeholders_are_not_references() {
        let (_d, repo) = repo();
        let text = "`out/reproduce/report.md`, `firmware/target/thumbv7em-none-eabihf/release/x`, \
                    `$OUT_DIR/gen.rs`, `DIR/report.md`, https://example.com/a/b.md, /dev/ttyUSB0, \
                    kN/mm, 1/2048 s\n";
        assert_eq!(md(&repo, text), vec![]);
        let text =
            "`data/models/rnn-H.json`, `docs/X.md`, `firmware/target`, `fuzz/artifacts/x/`\n";
        assert_eq!(md(&repo, text), vec![]);
    }

    #[test]
    fn braces_expand() {
        assert_eq!(
            expand_braces("data/models/rnn-{5,10}.json"),
            vec!["data/models/rnn-5.json", "data/models/rnn-10.json"]
        );
        let (_d, repo) = repo();
        assert_eq!(md(&repo, "`core/src/{lib,control}.rs`\n"), vec![]);
        assert_eq!(md(&repo, "`core/src/{lib,gone}.rs`\n").len(), 1);
    }

    #[test]
    fn section_citations_need_the_numbered_heading() {
        let (_d, repo) = repo();
        assert_eq!(
            md(&repo, "as docs/design.md §4 and docs/design.md §1.2 say\n"),
            vec![]
        );
        let f = md(
            &repo,
            "docs/design.md §5, [design.md §3](design.md#3-integrator)\n",
        );
        assert_eq!(f.len(), 3, "{f:?}"); // §5, §3 and the link's anchor
    }

    #[test]
    fn the_old_citations_are_refused() {
        let (_d, repo) = repo();
        let brief = concat!("DESIGN", " §4");
        let shared = concat!("../", "shared", "/DESIGN.md");
        let notes = concat!("notes", "/link.md");
        let brief_file = concat!("`shared", "/DESIGN.md` §2");
        for text in [brief, shared, notes, brief_file] {
            let f = check_text(
                &repo,
                Path::new("src/lib.rs"),
                &format!("// {text}\n"),
                Kind::Rust,
            );
            assert_eq!(f.len(), 1, "{text}: {f:?}");
        }
        // Comments only: the same text in code is not a citation.
        let code = format!("let s = \"{brief}\";\n");
        assert_eq!(
            check_text(&repo, Path::new("src/lib.rs"), &code, Kind::Rust),
            vec![]
        );
    }

    #[test]
    fn comments_are_found_outside_strings() {
        assert_eq!(comment_after("let u = \"a // b\"; // c", "//"), Some(" c"));
        assert_eq!(comment_after("x = \"https://a\"", "//"), None);
        assert_eq!(comment_after("key = 1 # why", "#"), Some(" why"));
    }
}
