//! The workspace's shape, checked: no two source files of a crate import
//! each other in a loop, no pam-lab file over 900 lines, the READMEs a
//! newcomer reads first within their lengths, and every row of a Markdown
//! table with its header's cells.
//!
//! The import graph is file-level: a file points at the file that defines
//! the module a path names (`crate::`, `super::`, `self::` or a child
//! module's name; its `use` statements, braces expanded, and the paths
//! written in its code), test modules and comments left out. A `mod`
//! declaration is not an import.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the workspace")
        .to_path_buf()
}

/// The files under `dir` whose extension is `ext`, in path order, not
/// under a `target/` or hidden directory.
fn files_with(dir: &Path, ext: &str, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if p.is_dir() {
            if name != "target" && !name.starts_with('.') {
                files_with(&p, ext, out);
            }
        } else if p.extension().is_some_and(|e| e == ext) {
            out.push(p);
        }
    }
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    files_with(dir, "rs", out);
}

/// The file's code with its comments removed and its string and char
/// literals emptied (one pass: line and nested block comments; plain, raw
/// and byte strings; char literals, not lifetimes), then without its test
/// modules (a `#[cfg(test)]` item and everything in its braces).
fn code_of(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let at = |i: usize| chars.get(i).copied().unwrap_or('\0');
    let mut code = String::with_capacity(text.len());
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if c == '/' && at(i + 1) == '/' {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && at(i + 1) == '*' {
            let mut depth = 0usize;
            while i < chars.len() {
                if chars[i] == '/' && at(i + 1) == '*' {
                    depth += 1;
                    i += 2;
                } else if chars[i] == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            code.push(' ');
        } else if (c == 'r' || (c == 'b' && at(i + 1) == 'r'))
            && (i == 0 || !is_ident_char(chars[i - 1]))
            && {
                let j = if c == 'b' { i + 2 } else { i + 1 };
                let mut k = j;
                while at(k) == '#' {
                    k += 1;
                }
                at(k) == '"'
            }
        {
            // A raw string: r"…", r#"…"#, br"…".
            let mut k = if c == 'b' { i + 2 } else { i + 1 };
            let mut hashes = 0;
            while at(k) == '#' {
                hashes += 1;
                k += 1;
            }
            k += 1;
            while k < chars.len() && !(chars[k] == '"' && (1..=hashes).all(|h| at(k + h) == '#')) {
                k += 1;
            }
            i = k + 1 + hashes;
            code.push_str("\"\"");
        } else if c == '"' {
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                i += if chars[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            code.push_str("\"\"");
        } else if c == '\'' && (i == 0 || !is_ident_char(chars[i - 1])) {
            // A char literal ('a', '\n', '\u{7f}'), or a lifetime ('a).
            let close = if at(i + 1) == '\\' {
                (i + 3..(i + 12).min(chars.len())).find(|&k| chars[k] == '\'')
            } else {
                (at(i + 2) == '\'').then_some(i + 2)
            };
            match close {
                Some(k) => {
                    code.push_str("' '");
                    i = k + 1;
                }
                None => {
                    code.push(c);
                    i += 1;
                }
            }
        } else {
            code.push(c);
            i += 1;
        }
    }
    // Cut `#[cfg(test)]` items: from the attribute to the end of the item's
    // braces (or its `;`).
    let mut out = String::new();
    let mut rest = code.as_str();
    while let Some(i) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..i]);
        let after = &rest[i..];
        let mut depth = 0usize;
        let mut end = after.len();
        for (j, c) in after.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth = depth.saturating_sub(1);
                    if depth == 0 {
                        end = j + 1;
                        break;
                    }
                }
                ';' if depth == 0 => {
                    end = j + 1;
                    break;
                }
                _ => {}
            }
        }
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// `a::{b, c::{d, e as f}}` → `a::b`, `a::c::d`, `a::c::e as f` (an alias
/// kept after ` as `).
fn expand(tree: &str) -> Vec<String> {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        // One path, its whitespace gone but for an alias's ` as `.
        return vec![match tree.split_once(" as ") {
            Some((p, a)) => format!("{} as {}", squeeze(p), squeeze(a)),
            None => squeeze(tree),
        }];
    };
    let prefix = squeeze(&tree[..open]);
    let close = tree.rfind('}').filter(|&c| c > open).unwrap_or(tree.len());
    let inner = &tree[open + 1..close];
    let (mut parts, mut depth, mut start) = (Vec::new(), 0usize, 0usize);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth = depth.saturating_sub(1),
            ',' if depth == 0 => {
                parts.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.trim().is_empty())
        .flat_map(|p| {
            expand(p)
                .into_iter()
                .map(|s| format!("{prefix}{s}"))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// `s` without whitespace.
fn squeeze(s: &str) -> String {
    s.chars().filter(|c| !c.is_whitespace()).collect()
}

/// The module path of a source file (`src/a/b.rs` and `src/a/b/mod.rs`:
/// `[a, b]`; `lib.rs`, `main.rs`: `[]`).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("under src");
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// A `use` item: the path it names and the name it brings in (`*`: all).
struct UseItem {
    path: Vec<String>,
    name: String,
}

/// What the import graph needs of one file.
struct FileInfo {
    module: Vec<String>,
    /// Names the file itself defines.
    defs: BTreeSet<String>,
    uses: Vec<UseItem>,
    /// Names the code outside its `use` statements may take from another
    /// file: types, constants, functions and macros called, paths' heads.
    body_idents: BTreeSet<String>,
    /// Paths (`a::b`) written in the code outside its `use` statements.
    body_paths: Vec<Vec<String>>,
}

/// The keywords after which a name is defined, not used.
const DEFINING: [&str; 9] = [
    "struct",
    "enum",
    "fn",
    "trait",
    "type",
    "const",
    "static",
    "union",
    "macro_rules",
];

fn is_ident_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

fn file_info(module: Vec<String>, text: &str) -> FileInfo {
    let code = code_of(text);
    let mut uses = Vec::new();
    let mut body = String::new();
    let mut rest = code.as_str();
    loop {
        let Some(i) = rest.find("use ") else {
            body.push_str(rest);
            break;
        };
        let word_start = rest[..i].chars().last().is_none_or(|c| !is_ident_char(c));
        let Some(end) = rest[i..].find(';').map(|e| i + e) else {
            body.push_str(rest);
            break;
        };
        if !word_start {
            body.push_str(&rest[..i + 4]);
            rest = &rest[i + 4..];
            continue;
        }
        body.push_str(&rest[..i]);
        for p in expand(&rest[i + 4..end]) {
            let (p, alias) = match p.split_once(" as ") {
                Some((p, a)) => (p.to_string(), Some(a.to_string())),
                None => (p, None),
            };
            let mut path: Vec<String> = p.split("::").map(str::to_string).collect();
            if path.last().is_some_and(|s| s == "self") {
                path.pop();
            }
            let Some(last) = path.last().cloned() else {
                continue;
            };
            let name = alias.unwrap_or(last);
            uses.push(UseItem { path, name });
        }
        rest = &rest[end + 1..];
    }
    let chars: Vec<char> = body.chars().collect();
    let (mut body_idents, mut body_paths) = (BTreeSet::new(), Vec::new());
    let mut defs = BTreeSet::new();
    let mut i = 0;
    let mut previous_word = String::new();
    while i < chars.len() {
        if is_ident_char(chars[i]) && (i == 0 || !is_ident_char(chars[i - 1])) {
            let mut j = i;
            while j < chars.len() && (is_ident_char(chars[j]) || chars[j] == ':') {
                j += 1;
            }
            let word: String = chars[i..j].iter().collect();
            let word = word.trim_end_matches(':');
            let first = word.split("::").next().unwrap_or("");
            if word.contains("::") {
                body_paths.push(word.split("::").map(str::to_string).collect());
                body_idents.insert(first.to_string());
            } else {
                // A name that can come from another file: a type or a
                // constant (capitalised), a function or macro called. A
                // lowercase name otherwise is a field or a variable.
                let next = chars[j..].iter().find(|c| !c.is_whitespace());
                let method = i > 0 && chars[i - 1] == '.';
                let defined_here = DEFINING.contains(&previous_word.as_str());
                if !method
                    && !defined_here
                    && (first.starts_with(|c: char| c.is_uppercase())
                        || matches!(next, Some('(' | '!')))
                {
                    body_idents.insert(first.to_string());
                }
            }
            if DEFINING.contains(&previous_word.as_str()) {
                defs.insert(word.to_string());
            }
            // A lifetime (`'static`) is no keyword.
            let lifetime = i > 0 && chars[i - 1] == '\'';
            previous_word = if lifetime {
                String::new()
            } else {
                word.to_string()
            };
            i = j;
        } else {
            if !chars[i].is_whitespace() && chars[i] != '!' {
                previous_word.clear();
            }
            i += 1;
        }
    }
    FileInfo {
        module,
        defs,
        uses,
        body_idents,
        body_paths,
    }
}

/// The crate's files by module path.
type Modules = BTreeMap<Vec<String>, (PathBuf, FileInfo)>;

/// The (module, name) pairs a resolution has asked already: re-exports
/// and globs may point back at each other.
type Seen = BTreeSet<(Vec<String>, String)>;

/// The module a path's leading segments name from module `from`, and the
/// segments left after it; `None` for a path into another crate.
fn module_prefix<'p>(
    modules: &Modules,
    from: &[String],
    path: &'p [String],
) -> Option<(Vec<String>, &'p [String])> {
    let (mut at, mut k) = match path.first().map(String::as_str) {
        Some("crate") => (Vec::new(), 1),
        Some("self") => (from.to_vec(), 1),
        Some("super") => {
            let mut m = from.to_vec();
            m.pop();
            (m, 1)
        }
        // A child module's name (edition 2018: `use b::B` in `a`).
        Some(child) => {
            let mut next = from.to_vec();
            next.push(child.to_string());
            if !modules.contains_key(&next) {
                return None;
            }
            (next, 1)
        }
        None => return None,
    };
    while k < path.len() {
        if path[k] == "super" {
            at.pop();
        } else {
            let mut next = at.clone();
            next.push(path[k].clone());
            if !modules.contains_key(&next) {
                break;
            }
            at = next;
        }
        k += 1;
    }
    Some((at, &path[k..]))
}

/// The file that defines `name` as module `module` sees it: its own
/// definition, or one it takes through a `use` (followed to the file that
/// defines it, through re-exports).
fn definer(modules: &Modules, module: &[String], name: &str, seen: &mut Seen) -> Option<PathBuf> {
    let (file, info) = modules.get(module)?;
    if !seen.insert((module.to_vec(), name.to_string())) {
        return None;
    }
    if info.defs.contains(name) {
        return Some(file.clone());
    }
    let mut child = module.to_vec();
    child.push(name.to_string());
    if let Some((f, _)) = modules.get(&child) {
        return Some(f.clone());
    }
    for u in info.uses.iter().filter(|u| u.name == name) {
        if let Some(f) = path_definer(modules, module, &u.path, seen) {
            return Some(f);
        }
    }
    for u in info.uses.iter().filter(|u| u.name == "*") {
        let prefix = &u.path[..u.path.len() - 1];
        if let Some((m, [])) = module_prefix(modules, module, prefix) {
            if let Some(f) = definer(modules, &m, name, seen) {
                return Some(f);
            }
        }
    }
    None
}

/// The file that defines what `path` names from module `from`.
fn path_definer(
    modules: &Modules,
    from: &[String],
    path: &[String],
    seen: &mut Seen,
) -> Option<PathBuf> {
    let (at, rest) = module_prefix(modules, from, path)?;
    match rest.first() {
        None => modules.get(&at).map(|(f, _)| f.clone()),
        Some(name) => {
            definer(modules, &at, name, seen).or_else(|| modules.get(&at).map(|(f, _)| f.clone()))
        }
    }
}

/// The import edges between one crate's source files: a file points at
/// the file that defines each name it uses (a name its `use` statements
/// bring in and its code uses, or a path its code writes). A `use` whose
/// name the code does not use (a re-export) is no edge.
fn import_graph(src: &Path) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    // `src/bin/x.rs` files, and `main.rs` beside a `lib.rs`, are crates of
    // their own; a file named `tests.rs` is a test module.
    let has_lib = src.join("lib.rs").is_file();
    let modules: Modules = files
        .into_iter()
        .filter(|f| !f.starts_with(src.join("bin")) && f.file_stem().is_none_or(|s| s != "tests"))
        .filter(|f| !(has_lib && *f == src.join("main.rs")))
        .map(|f| {
            let module = module_of(src, &f);
            let info = file_info(
                module.clone(),
                &std::fs::read_to_string(&f).expect("readable source"),
            );
            (module, (f, info))
        })
        .collect();
    let mut graph = BTreeMap::new();
    for (f, info) in modules.values() {
        let m = &info.module;
        let mut edges = BTreeSet::new();
        for u in &info.uses {
            if u.name == "*" {
                let prefix = &u.path[..u.path.len() - 1];
                if let Some((g, [])) = module_prefix(&modules, m, prefix) {
                    for ident in &info.body_idents {
                        edges.extend(definer(&modules, &g, ident, &mut Seen::new()));
                    }
                }
            } else if info.body_idents.contains(&u.name) {
                edges.extend(path_definer(&modules, m, &u.path, &mut Seen::new()));
            }
        }
        for p in &info.body_paths {
            edges.extend(path_definer(&modules, m, p, &mut Seen::new()));
        }
        edges.remove(f);
        graph.insert(f.clone(), edges);
    }
    graph
}

/// One loop of files, if the graph has any.
fn a_cycle(graph: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Option<Vec<PathBuf>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Open,
        Done,
    }
    fn visit(
        n: &PathBuf,
        graph: &BTreeMap<PathBuf, BTreeSet<PathBuf>>,
        marks: &mut BTreeMap<PathBuf, Mark>,
        stack: &mut Vec<PathBuf>,
    ) -> Option<Vec<PathBuf>> {
        marks.insert(n.clone(), Mark::Open);
        stack.push(n.clone());
        for m in graph.get(n).into_iter().flatten() {
            match marks.get(m).copied().unwrap_or(Mark::New) {
                Mark::Open => {
                    let at = stack.iter().position(|s| s == m).unwrap_or(0);
                    let mut cycle = stack[at..].to_vec();
                    cycle.push(m.clone());
                    return Some(cycle);
                }
                Mark::New => {
                    if let Some(c) = visit(m, graph, marks, stack) {
                        return Some(c);
                    }
                }
                Mark::Done => {}
            }
        }
        stack.pop();
        marks.insert(n.clone(), Mark::Done);
        None
    }
    let mut marks = BTreeMap::new();
    for n in graph.keys() {
        if marks.get(n).copied().unwrap_or(Mark::New) == Mark::New {
            if let Some(c) = visit(n, graph, &mut marks, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

const CRATES: [&str; 7] = [
    "pam-core", "firmware", "host-sim", "pam-lab", "bench-m4", "fuzz", "tests",
];

#[test]
fn no_two_files_of_a_crate_import_each_other_in_a_loop() {
    let root = workspace();
    let mut loops = Vec::new();
    for c in CRATES {
        let src = root.join(c).join("src");
        if !src.is_dir() {
            continue;
        }
        if let Some(cycle) = a_cycle(&import_graph(&src)) {
            let names: Vec<String> = cycle
                .iter()
                .map(|p| p.strip_prefix(&root).unwrap_or(p).display().to_string())
                .collect();
            loops.push(names.join(" -> "));
        }
    }
    assert!(loops.is_empty(), "import loops:\n{}", loops.join("\n"));
}

/// The loop [`a_cycle`] finds in a crate of `files` (path under `src/`,
/// text), written to a temporary folder.
fn loop_in(files: &[(&str, &str)]) -> Option<Vec<PathBuf>> {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("pam-structure-{}-{n}", std::process::id()));
    let src = dir.join("src");
    for (path, text) in files {
        let p = src.join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    let cycle = a_cycle(&import_graph(&src));
    std::fs::remove_dir_all(&dir).unwrap();
    cycle
}

#[test]
fn the_loop_finder_finds_a_parent_and_child_that_import_each_other() {
    // The check itself, on crates written here: `a/mod.rs` uses `B` of
    // `a/b.rs`, which takes a helper from `a/mod.rs`.
    let parent = |body: &str| {
        format!("//! super::x in a comment\npub mod b;\npub use b::B;\n{body}\npub fn helper() -> u8 {{ 1 }}\n")
    };
    let child =
        "pub struct B;\nimpl B { pub const ONE: u8 = 1; pub fn f() -> u8 { super::helper() } }\n";
    let lib = ("lib.rs", "pub mod a;\npub use a::B;\n");
    // A re-export alone is no import: no loop.
    assert_eq!(
        loop_in(&[lib, ("a/mod.rs", &parent("")), ("a/b.rs", child)]),
        None
    );
    // The parent uses what it re-exports: the loop.
    let used = loop_in(&[
        lib,
        ("a/mod.rs", &parent("pub fn one() -> u8 { B::ONE }")),
        ("a/b.rs", child),
    ])
    .expect("the loop a/mod.rs <-> a/b.rs");
    assert_eq!(used.len(), 3, "{used:?}");
    assert!(
        used.iter()
            .all(|p| p.ends_with("a/mod.rs") || p.ends_with("a/b.rs")),
        "{used:?}"
    );
    // The same through an alias.
    let aliased = parent("use self::b::B as Bee;\npub fn one() -> u8 { Bee::ONE }");
    assert!(loop_in(&[lib, ("a/mod.rs", &aliased), ("a/b.rs", child)]).is_some());
    // The child's way back only in comments, strings and a test module:
    // no loop.
    let quiet =
        "pub struct B;\n// super::helper()\n/* super::helper() /* nested */ super::helper() */\n\
                 const S: &str = \"super::helper() // \\\" super::helper()\";\n\
                 const R: &str = r#\"super::helper() \"# ;\nconst C: char = '{';\n\
                 impl B { pub const ONE: u8 = 1; }\n\
                 #[cfg(test)]\nmod tests { fn t() { super::super::helper(); } }\n";
    let with_b = parent("pub fn one() -> u8 { B::ONE }");
    assert_eq!(
        loop_in(&[lib, ("a/mod.rs", &with_b), ("a/b.rs", quiet)]),
        None
    );
    // A loop through the crate root, with a binary beside it.
    let root = loop_in(&[
        ("lib.rs", "pub mod a;\npub fn root() -> u8 { a::B::ONE }\n"),
        ("main.rs", "fn main() {}\n"),
        ("a/mod.rs", "pub mod b;\npub use b::B;\n"),
        (
            "a/b.rs",
            "pub struct B;\nimpl B { pub const ONE: u8 = 1; pub fn f() -> u8 { crate::root() } }\n",
        ),
    ]);
    assert!(root.is_some_and(|c| c.iter().any(|p| p.ends_with("lib.rs"))));
}

fn lines_of(path: &Path) -> usize {
    std::fs::read_to_string(path).map_or(0, |t| t.lines().count())
}

#[test]
fn no_pam_lab_file_is_over_900_lines() {
    let root = workspace().join("pam-lab");
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    rust_files(&root.join("tests"), &mut files);
    rust_files(&root.join("benches"), &mut files);
    let long: Vec<String> = files
        .iter()
        .filter(|f| lines_of(f) > 900)
        .map(|f| format!("{}: {} lines", f.display(), lines_of(f)))
        .collect();
    assert!(files.len() > 20, "{} files found", files.len());
    assert!(long.is_empty(), "{}", long.join("\n"));
}

#[test]
fn the_first_readmes_are_short() {
    let root = workspace();
    for (readme, most) in [("README.md", 150), ("firmware/README.md", 300)] {
        let n = lines_of(&root.join(readme));
        assert!(n > 0, "{readme} missing");
        assert!(n <= most, "{readme}: {n} lines, at most {most}");
    }
}

/// The cell separators of a table row: `|` outside code spans, not
/// escaped.
fn table_pipes(row: &str) -> usize {
    let (mut n, mut code, mut escaped) = (0, false, false);
    for c in row.trim().chars() {
        match c {
            '`' if !escaped => code = !code,
            '|' if !code && !escaped => n += 1,
            _ => {}
        }
        escaped = c == '\\';
    }
    n
}

/// `file:line: reason` for each row of a table (lines starting with `|`,
/// outside fenced code) whose cells are not its header's.
fn ragged_table_rows(name: &str, text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let (mut fenced, mut header) = (false, None);
    for (i, line) in text.lines().enumerate() {
        if line.starts_with("```") {
            fenced = !fenced;
        }
        if fenced || !line.starts_with('|') {
            header = None;
            continue;
        }
        let n = table_pipes(line);
        match header {
            None => header = Some(n),
            Some(h) if h != n => out.push(format!(
                "{name}:{}: {} cells, the header has {}",
                i + 1,
                n.saturating_sub(1),
                h.saturating_sub(1)
            )),
            Some(_) => {}
        }
    }
    out
}

#[test]
fn every_table_row_has_its_headers_cells() {
    let root = workspace();
    let mut files = Vec::new();
    files_with(&root, "md", &mut files);
    assert!(files.len() > 5, "{} Markdown files found", files.len());
    let ragged: Vec<String> = files
        .iter()
        .flat_map(|f| {
            let text = std::fs::read_to_string(f).unwrap_or_default();
            let name = f.strip_prefix(&root).unwrap_or(f).display().to_string();
            ragged_table_rows(&name, &text)
        })
        .collect();
    assert!(ragged.is_empty(), "{}", ragged.join("\n"));
}

#[test]
fn the_table_check_finds_a_row_written_over_with_another_tables() {
    let table =
        "| a | b | c |\n|---|---|---|\n| `x|y` | 2 \\| 3 | 4 |\n| 1 | 2 |\n\n| d |\n|---|\n";
    assert_eq!(
        ragged_table_rows("t.md", table),
        vec!["t.md:4: 2 cells, the header has 3".to_string()]
    );
    assert!(ragged_table_rows("t.md", "```\n| a |\n| b | c |\n```\n").is_empty());
}
