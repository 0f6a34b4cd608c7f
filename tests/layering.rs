//! The workspace's import structure: no circle of imports inside any crate, and arpa-core's
//! layers point one way (base ← per-photon stages ← renderer layer ← GPU layer).
//!
//! The check reads each crate's sources (no compiler involved): it follows `mod` declarations
//! from `lib.rs`/`main.rs`, tokenises every file (comments, strings and character literals
//! removed) and collects the paths that name another module of the same crate: `use` trees
//! (`use crate::a::{b::X, c}`), paths in code (`crate::a::f()`, `super::b::Y`, `self::c`) and
//! paths that start at a child module (`use child::X` in the parent). A path counts as an
//! import of the deepest module it names, at file granularity (an inline module belongs to
//! its file). Test code (`#[cfg(test)]` items and the files they declare) is left out: it
//! imports fixtures from anywhere and nothing imports it back.
//!
//! An import circle is reported with the modules on it and where each edge is written; an
//! upward import in arpa-core names both modules and their layers. `planted_*` tests plant a
//! circle and an upward import, in a small tree and in a copy of arpa-core, and require the
//! check to name the modules involved.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A module of a crate: its path from the crate root (`["gather", "estimate"]`; the root is
/// `[]`) and the file that holds it.
#[derive(Debug, Clone)]
struct Module {
    path: Vec<String>,
    file: PathBuf,
}

/// Where an import is written: file and line.
#[derive(Debug, Clone)]
struct Site {
    file: PathBuf,
    line: usize,
}

/// One crate's module graph: modules by name (`a::b`, the root is `crate`) and the imports
/// between file modules, each with the first place it is written.
#[derive(Debug, Default)]
struct Graph {
    modules: BTreeMap<String, Module>,
    /// (from, to) → where.
    edges: BTreeMap<(String, String), Site>,
}

fn name_of(path: &[String]) -> String {
    if path.is_empty() { "crate".to_string() } else { path.join("::") }
}

// ---------------------------------------------------------------------------------------
// Tokens

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    /// `::`
    PathSep,
    Punct(char),
}

/// Tokenises Rust source with comments, string, byte-string, raw-string and character
/// literals and numbers dropped; lifetimes become identifiers (harmless: never a module).
fn tokenize(src: &str) -> Vec<(Tok, usize)> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0usize, 1usize);
    let count_lines = |from: usize, to: usize, c: &[char]| c[from..to.min(c.len())].iter().filter(|&&x| x == '\n').count();
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied().unwrap_or('\0');
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && next == '/' {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == '*' {
            let start = i;
            let mut depth = 0usize;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            line += count_lines(start, i, &c);
        } else if (ch == 'r' || ch == 'b') && raw_string_start(&c, i).is_some() {
            let (hashes, body) = raw_string_start(&c, i).unwrap();
            let start = i;
            i = body;
            loop {
                if i >= c.len() {
                    break;
                }
                if c[i] == '"' && (0..hashes).all(|k| c.get(i + 1 + k) == Some(&'#')) {
                    i += 1 + hashes;
                    break;
                }
                i += 1;
            }
            line += count_lines(start, i, &c);
        } else if ch == '"' || (ch == 'b' && next == '"') || (ch == 'c' && next == '"') {
            let start = i;
            i += if ch == '"' { 1 } else { 2 };
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            line += count_lines(start, i, &c);
        } else if ch == '\'' || (ch == 'b' && next == '\'') {
            let q = if ch == '\'' { i } else { i + 1 };
            if c.get(q + 1) == Some(&'\\') {
                // Escaped character literal.
                i = q + 2;
                while i < c.len() && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if c.get(q + 2) == Some(&'\'') {
                i = q + 3;
            } else {
                // A lifetime or label: the identifier follows.
                i = q + 1;
            }
        } else if ch.is_alphabetic() || ch == '_' {
            if ch == 'r' && next == '#' {
                i += 2;
            }
            let id_start = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            out.push((Tok::Ident(c[id_start..i].iter().collect()), line));
        } else if ch.is_ascii_digit() {
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_' || (c[i] == '.' && c.get(i + 1).is_some_and(|d| d.is_ascii_digit()))) {
                i += 1;
            }
        } else if ch == ':' && next == ':' {
            out.push((Tok::PathSep, line));
            i += 2;
        } else {
            out.push((Tok::Punct(ch), line));
            i += 1;
        }
    }
    out
}

/// `r"`, `r#"`, `br##"` …: the number of `#` and the index after the opening quote.
fn raw_string_start(c: &[char], i: usize) -> Option<(usize, usize)> {
    let mut j = i;
    if c.get(j) == Some(&'b') {
        j += 1;
    }
    if c.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    let mut hashes = 0;
    while c.get(j) == Some(&'#') {
        hashes += 1;
        j += 1;
    }
    (c.get(j) == Some(&'"')).then_some((hashes, j + 1))
}

fn is_ident(t: Option<&(Tok, usize)>, s: &str) -> bool {
    matches!(t, Some((Tok::Ident(x), _)) if x == s)
}

fn is_punct(t: Option<&(Tok, usize)>, p: char) -> bool {
    matches!(t, Some((Tok::Punct(x), _)) if *x == p)
}

/// The index after the item that starts at `i` (after its attributes): the `;` that ends it
/// at its own depth, or the `}` that closes its first block.
fn skip_item(toks: &[(Tok, usize)], mut i: usize) -> usize {
    let mut depth = 0i32;
    while i < toks.len() {
        match &toks[i].0 {
            Tok::Punct('{') | Tok::Punct('(') | Tok::Punct('[') => depth += 1,
            Tok::Punct('}') | Tok::Punct(')') | Tok::Punct(']') => {
                depth -= 1;
                if depth == 0 && toks[i].0 == Tok::Punct('}') {
                    return i + 1;
                }
            }
            Tok::Punct(';') if depth == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    i
}

/// Whether the attribute starting at `i` (`#`) is `#[cfg(test)]`, and the index after it.
fn attribute(toks: &[(Tok, usize)], i: usize) -> Option<(bool, usize)> {
    if !is_punct(toks.get(i), '#') {
        return None;
    }
    let mut j = i + 1;
    if is_punct(toks.get(j), '!') {
        j += 1;
    }
    if !is_punct(toks.get(j), '[') {
        return None;
    }
    let test = is_ident(toks.get(j + 1), "cfg") && is_punct(toks.get(j + 2), '(') && is_ident(toks.get(j + 3), "test") && is_punct(toks.get(j + 4), ')');
    let mut depth = 0;
    while j < toks.len() {
        match toks[j].0 {
            Tok::Punct('[') => depth += 1,
            Tok::Punct(']') => {
                depth -= 1;
                if depth == 0 {
                    return Some((test, j + 1));
                }
            }
            _ => {}
        }
        j += 1;
    }
    Some((test, j))
}

// ---------------------------------------------------------------------------------------
// Reading a crate

/// A path found in a file: its segments as written, the inline module path it was written
/// in (absolute), and its line.
struct RawPath {
    segments: Vec<String>,
    scope: Vec<String>,
    line: usize,
}

/// What one file declares and uses.
struct FileScan {
    /// `mod x;` declarations (not `#[cfg(test)]`): (inline scope, name).
    file_mods: Vec<(Vec<String>, String)>,
    /// Inline `mod x { … }` modules (absolute paths).
    inline_mods: Vec<Vec<String>>,
    paths: Vec<RawPath>,
    /// `pub use` items: (module, name it is visible as, path it names).
    reexports: Vec<(Vec<String>, String, RawPath)>,
}

/// Expands a `use` tree starting at `i` (after `use`), appending every full path. Returns
/// the index after the tree.
fn use_tree(toks: &[(Tok, usize)], mut i: usize, prefix: &[String], out: &mut Vec<(Vec<String>, Option<String>, usize)>) -> usize {
    let mut path = prefix.to_vec();
    let mut alias = None;
    let line = toks.get(i).map_or(0, |t| t.1);
    if matches!(toks.get(i), Some((Tok::PathSep, _))) {
        // `::extern_crate::…`: not this crate.
        path.push("::".to_string());
        i += 1;
    }
    loop {
        match toks.get(i) {
            Some((Tok::Ident(s), _)) if s == "as" => {
                if let Some((Tok::Ident(a), _)) = toks.get(i + 1) {
                    alias = Some(a.clone());
                }
                i += 2;
                break;
            }
            Some((Tok::Ident(s), _)) => {
                path.push(s.clone());
                i += 1;
                if matches!(toks.get(i), Some((Tok::PathSep, _))) {
                    i += 1;
                    continue;
                }
                break;
            }
            Some((Tok::Punct('*'), _)) => {
                alias = Some("*".to_string());
                i += 1;
                break;
            }
            Some((Tok::Punct('{'), _)) => {
                i += 1;
                loop {
                    if is_punct(toks.get(i), '}') {
                        i += 1;
                        break;
                    }
                    if i >= toks.len() {
                        return i;
                    }
                    i = use_tree(toks, i, &path, out);
                    if is_punct(toks.get(i), ',') {
                        i += 1;
                    }
                }
                return i;
            }
            _ => break,
        }
    }
    out.push((path, alias, line));
    i
}

fn scan_file(src: &str, module: &[String]) -> FileScan {
    let toks = tokenize(src);
    let mut scan = FileScan { file_mods: Vec::new(), inline_mods: Vec::new(), paths: Vec::new(), reexports: Vec::new() };
    // Stack of (inline module name, brace depth at which its block closes).
    let mut scope: Vec<(String, i32)> = Vec::new();
    let mut depth = 0i32;
    let mut i = 0;
    let current = |scope: &[(String, i32)]| -> Vec<String> {
        let mut p = module.to_vec();
        p.extend(scope.iter().map(|s| s.0.clone()));
        p
    };
    while i < toks.len() {
        if let Some((test, after)) = attribute(&toks, i) {
            i = if test { skip_item(&toks, after) } else { after };
            continue;
        }
        match &toks[i].0 {
            Tok::Punct('{') => {
                depth += 1;
                i += 1;
            }
            Tok::Punct('}') => {
                if scope.last().is_some_and(|s| s.1 == depth) {
                    scope.pop();
                }
                depth -= 1;
                i += 1;
            }
            Tok::Ident(kw) if kw == "mod" => {
                if let Some((Tok::Ident(name), _)) = toks.get(i + 1) {
                    if is_punct(toks.get(i + 2), ';') {
                        scan.file_mods.push((scope.iter().map(|s| s.0.clone()).collect(), name.clone()));
                        i += 3;
                        continue;
                    }
                    if is_punct(toks.get(i + 2), '{') {
                        depth += 1;
                        scope.push((name.clone(), depth));
                        scan.inline_mods.push(current(&scope));
                        i += 3;
                        continue;
                    }
                }
                i += 1;
            }
            Tok::Ident(kw) if kw == "use" => {
                let mut found = Vec::new();
                let end = use_tree(&toks, i + 1, &[], &mut found);
                // `pub use` / `pub(crate) use`: a name other modules may import from here.
                let public = (i >= 1 && is_ident(toks.get(i - 1), "pub")) || (i >= 4 && is_ident(toks.get(i - 4), "pub") && is_punct(toks.get(i - 3), '(') && is_punct(toks.get(i - 1), ')'));
                for (segments, alias, line) in found {
                    let name = alias.or_else(|| segments.last().cloned()).unwrap_or_default();
                    if public && name != "*" && name != "_" {
                        scan.reexports.push((current(&scope), name, RawPath { segments: segments.clone(), scope: current(&scope), line }));
                    }
                    scan.paths.push(RawPath { segments, scope: current(&scope), line });
                }
                i = end.max(i + 1);
            }
            Tok::Ident(first) if matches!(toks.get(i + 1), Some((Tok::PathSep, _))) => {
                // A path in code: `a::b::c` (not preceded by `::`, which would make it the
                // tail of a longer path).
                let preceded = i > 0 && matches!(toks[i - 1].0, Tok::PathSep);
                let line = toks[i].1;
                let mut segments = vec![first.clone()];
                let mut j = i + 1;
                while matches!(toks.get(j), Some((Tok::PathSep, _))) {
                    match toks.get(j + 1) {
                        Some((Tok::Ident(s), _)) => {
                            segments.push(s.clone());
                            j += 2;
                        }
                        _ => break,
                    }
                }
                if !preceded {
                    scan.paths.push(RawPath { segments, scope: current(&scope), line });
                }
                i = j.max(i + 1);
            }
            _ => i += 1,
        }
    }
    scan
}

/// Reads the crate whose root file is `root` (its `lib.rs` or `main.rs`).
fn read_crate(root: &Path) -> Result<Graph, String> {
    let mut graph = Graph::default();
    // Raw paths per file module, resolved once every module is known.
    let mut pending: Vec<(String, RawPath)> = Vec::new();
    let mut reexports = Reexports::new();
    // Inline module → the file module it belongs to.
    let mut owner: BTreeMap<Vec<String>, String> = BTreeMap::new();
    let mut queue = vec![(Vec::<String>::new(), root.to_path_buf())];
    while let Some((path, file)) = queue.pop() {
        let src = std::fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
        let scan = scan_file(&src, &path);
        let name = name_of(&path);
        owner.insert(path.clone(), name.clone());
        for m in &scan.inline_mods {
            owner.insert(m.clone(), name.clone());
        }
        // Children of a `foo.rs` live in `foo/`; of `lib.rs`, `main.rs`, `mod.rs` beside it.
        let stem = file.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let dir = if path.is_empty() || stem == "mod" { file.parent().unwrap().to_path_buf() } else { file.with_extension("") };
        for (inline, child) in &scan.file_mods {
            let mut d = dir.clone();
            for s in inline {
                d.push(s);
            }
            let flat = d.join(format!("{child}.rs"));
            let nested = d.join(child).join("mod.rs");
            let child_file = if flat.is_file() { flat } else if nested.is_file() { nested } else { return Err(format!("{}: `mod {child};` has no file", file.display())) };
            let mut child_path = path.clone();
            child_path.extend(inline.iter().cloned());
            child_path.push(child.clone());
            queue.push((child_path, child_file));
        }
        graph.modules.insert(name.clone(), Module { path: path.clone(), file: file.clone() });
        for p in scan.paths {
            pending.push((name.clone(), p));
        }
        for (module, item, p) in scan.reexports {
            reexports.insert((module, item), p);
        }
    }
    let known: BTreeSet<Vec<String>> = owner.keys().cloned().collect();
    for (from, raw) in pending {
        let Some(target) = resolve(&raw, &known, &reexports, 0) else { continue };
        let to = owner[&target].clone();
        if to != from {
            let file = graph.modules[&from].file.clone();
            graph.edges.entry((from, to)).or_insert(Site { file, line: raw.line });
        }
    }
    Ok(graph)
}

/// `pub use` items by (module, name): the path each names.
type Reexports = BTreeMap<(Vec<String>, String), RawPath>;

/// The module a path names, if it names one of this crate: the deepest module on it, or,
/// where the next name is re-exported there (`pub use`), the module the re-export names.
fn resolve(raw: &RawPath, known: &BTreeSet<Vec<String>>, reexports: &Reexports, depth: usize) -> Option<Vec<String>> {
    let segs = &raw.segments;
    let first = segs.first()?;
    let (mut base, rest): (Vec<String>, &[String]) = match first.as_str() {
        "crate" => (Vec::new(), &segs[1..]),
        "self" => (raw.scope.clone(), &segs[1..]),
        "super" => {
            let mut b = raw.scope.clone();
            let mut k = 0;
            while segs.get(k).is_some_and(|s| s == "super") {
                b.pop()?;
                k += 1;
            }
            (b, &segs[k..])
        }
        _ => {
            // A path that starts at a child module of the scope (2018 paths).
            let mut child = raw.scope.clone();
            child.push(first.clone());
            if !known.contains(&child) {
                return None;
            }
            (raw.scope.clone(), &segs[..])
        }
    };
    let mut deepest = base.clone();
    for s in rest {
        base.push(s.clone());
        if known.contains(&base) {
            deepest = base.clone();
        } else {
            // Follow a re-export (bounded: a `pub use` may name itself through a glob).
            if let Some(target) = reexports.get(&(deepest.clone(), s.clone()))
                && depth < 8
                && !std::ptr::eq(target, raw)
            {
                return resolve(target, known, reexports, depth + 1).or(Some(deepest));
            }
            break;
        }
    }
    Some(deepest)
}

// ---------------------------------------------------------------------------------------
// Checks

/// Every import circle: for each strongly connected set of modules, one shortest circle
/// through its first module, written `a → b → a` with where each import is.
fn circles(graph: &Graph) -> Vec<String> {
    let names: Vec<&String> = graph.modules.keys().collect();
    let index: BTreeMap<&String, usize> = names.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let mut adj = vec![Vec::new(); names.len()];
    for (from, to) in graph.edges.keys() {
        if let (Some(&a), Some(&b)) = (index.get(from), index.get(to)) {
            adj[a].push(b);
        }
    }
    // Tarjan's strongly connected components, iteratively.
    let n = names.len();
    let (mut idx, mut low, mut on) = (vec![usize::MAX; n], vec![0; n], vec![false; n]);
    let (mut stack, mut comps, mut counter) = (Vec::new(), Vec::new(), 0);
    for s in 0..n {
        if idx[s] != usize::MAX {
            continue;
        }
        let mut work = vec![(s, 0usize)];
        while let Some(&(v, k)) = work.last() {
            if k == 0 {
                idx[v] = counter;
                low[v] = counter;
                counter += 1;
                stack.push(v);
                on[v] = true;
            }
            if let Some(&w) = adj[v].get(k) {
                work.last_mut().unwrap().1 += 1;
                if idx[w] == usize::MAX {
                    work.push((w, 0));
                } else if on[w] {
                    low[v] = low[v].min(idx[w]);
                }
                continue;
            }
            work.pop();
            if let Some(&(u, _)) = work.last() {
                low[u] = low[u].min(low[v]);
            }
            if low[v] == idx[v] {
                let mut comp = Vec::new();
                while let Some(w) = stack.pop() {
                    on[w] = false;
                    comp.push(w);
                    if w == v {
                        break;
                    }
                }
                if comp.len() > 1 {
                    comps.push(comp);
                }
            }
        }
    }
    let mut out = Vec::new();
    for comp in comps {
        let members: BTreeSet<usize> = comp.iter().copied().collect();
        let start = *members.iter().next().unwrap();
        // Breadth-first from `start` back to itself inside the component.
        let mut prev = vec![usize::MAX; n];
        let mut frontier = std::collections::VecDeque::from([start]);
        let mut end = None;
        'bfs: while let Some(v) = frontier.pop_front() {
            for &w in &adj[v] {
                if !members.contains(&w) {
                    continue;
                }
                if w == start {
                    end = Some(v);
                    break 'bfs;
                }
                if prev[w] == usize::MAX {
                    prev[w] = v;
                    frontier.push_back(w);
                }
            }
        }
        let mut back = Vec::new();
        let mut v = end.unwrap();
        while v != start {
            back.push(v);
            v = prev[v];
        }
        let mut cycle = vec![start];
        cycle.extend(back.into_iter().rev());
        cycle.push(start);
        let mut line = cycle.iter().map(|&c| format!("`{}`", names[c])).collect::<Vec<_>>().join(" → ");
        line.push_str(" (");
        for w in cycle.windows(2) {
            let site = &graph.edges[&(names[w[0]].clone(), names[w[1]].clone())];
            let _ = write!(line, "{}:{} uses `{}`; ", site.file.display(), site.line, names[w[1]]);
        }
        line.truncate(line.len() - 2);
        line.push(')');
        if members.len() + 1 > cycle.len() {
            let all: Vec<&str> = members.iter().map(|&m| names[m].as_str()).collect();
            let _ = write!(line, "; the {} modules that reach each other: {}", all.len(), all.join(", "));
        }
        out.push(line);
    }
    out
}

/// A crate's layers, lowest first: each a name and the top-level modules in it. Modules
/// not listed (the crate root) may import any layer; nothing may import them.
struct Layers {
    layers: &'static [(&'static str, &'static [&'static str])],
}

/// arpa-core's layers (DEVELOPERS.md, "Layout").
const CORE_LAYERS: Layers = Layers {
    layers: &[
        ("base", &["base"]),
        ("per-photon stages", &["emit", "propagate", "store", "gather", "accumulate"]),
        ("renderer layer", &["render"]),
        ("GPU layer", &["gpu"]),
    ],
};

impl Layers {
    fn rank(&self, module: &Module) -> Option<(usize, &'static str)> {
        let top = module.path.first()?;
        self.layers.iter().enumerate().find(|(_, (_, mods))| mods.contains(&top.as_str())).map(|(r, (n, _))| (r, *n))
    }
}

/// Every import of a module from a higher layer (or of the crate root from a layered module).
fn upward_imports(graph: &Graph, layers: &Layers) -> Vec<String> {
    let mut out = Vec::new();
    for ((from, to), site) in &graph.edges {
        let (a, b) = (&graph.modules[from], &graph.modules[to]);
        let Some((ra, na)) = layers.rank(a) else { continue };
        let problem = match layers.rank(b) {
            Some((rb, nb)) if rb > ra => format!("`{from}` ({na}) imports `{to}` ({nb}), a higher layer"),
            None => format!("`{from}` ({na}) imports `{to}`, which is above every layer"),
            _ => continue,
        };
        out.push(format!("{problem} at {}:{}", site.file.display(), site.line));
    }
    out
}

/// Checks one crate: circles, and upward imports where it has layers.
fn check(root: &Path, layers: Option<&Layers>) -> Result<Graph, Vec<String>> {
    let graph = read_crate(root).map_err(|e| vec![e])?;
    let mut problems: Vec<String> = circles(&graph).into_iter().map(|c| format!("import circle: {c}")).collect();
    if let Some(l) = layers {
        problems.extend(upward_imports(&graph, l).into_iter().map(|u| format!("upward import: {u}")));
    }
    if problems.is_empty() { Ok(graph) } else { Err(problems) }
}

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every crate root of the workspace, with the layers the crate declares.
fn crate_roots() -> Vec<(PathBuf, Option<&'static Layers>)> {
    let ws = workspace();
    let mut roots = vec![(ws.join("arpa-core/src/lib.rs"), Some(&CORE_LAYERS))];
    for dir in ["", "arpa-cpu", "arpa-wgpu", "arpa-vk", "conformance"] {
        for file in ["src/lib.rs", "src/main.rs"] {
            let p = ws.join(dir).join(file);
            if p.is_file() {
                roots.push((p, None));
            }
        }
    }
    roots
}

#[test]
fn no_import_circle_and_no_upward_import_in_the_workspace() {
    let mut problems = Vec::new();
    for (root, layers) in crate_roots() {
        match check(&root, layers) {
            Ok(graph) => {
                // The check reads something: every library has imports between its modules.
                let library = root.ends_with("lib.rs");
                assert!(!library || graph.modules.len() >= 2 && !graph.edges.is_empty(), "{}: read {} modules and {} imports; the scan is broken", root.display(), graph.modules.len(), graph.edges.len());
            }
            Err(p) => problems.extend(p.into_iter().map(|p| format!("{}: {p}", root.display()))),
        }
    }
    assert!(problems.is_empty(), "{} layering problems:\n{}", problems.len(), problems.join("\n"));
}

#[test]
fn arpa_core_has_its_layers_and_reads_fully() {
    let graph = read_crate(&workspace().join("arpa-core/src/lib.rs")).unwrap();
    // Every module but the root is in a layer, so the layer check covers the whole crate.
    let unlayered: Vec<&String> = graph.modules.iter().filter(|(_, m)| !m.path.is_empty() && CORE_LAYERS.rank(m).is_none()).map(|(n, _)| n).collect();
    assert!(unlayered.is_empty(), "arpa-core modules outside every layer: {unlayered:?}");
    assert!(graph.modules.len() >= 30 && graph.edges.len() >= 60, "arpa-core: {} modules, {} imports read", graph.modules.len(), graph.edges.len());
    // A known import is seen (the estimate sums footprints with the kernel).
    assert!(graph.edges.keys().any(|(a, b)| a.ends_with("estimate") && b.ends_with("kernel")), "the scan missed estimate → kernel");
}

// ---------------------------------------------------------------------------------------
// The check fails where it must.

fn write_tree(dir: &Path, files: &[(&str, &str)]) {
    for (name, text) in files {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
}

#[test]
fn planted_circle_in_a_small_tree_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_tree(
        dir.path(),
        &[
            ("lib.rs", "pub mod a;\npub mod b;\npub mod c;\n"),
            ("a.rs", "// crate::c::Z in a comment is no import\nuse crate::b::{X, inner::W};\npub struct Y;\n#[cfg(test)]\nmod tests { use crate::c::Z; }\n"),
            ("b/mod.rs", "pub mod inner;\npub struct X;\npub fn f() -> super::a::Y { super::a::Y }\n"),
            ("b/inner.rs", "pub struct W;\nconst S: &str = \"crate::c::Z\";\n"),
            ("c.rs", "use crate::a::Y;\npub struct Z;\n"),
        ],
    );
    let problems = check(&dir.path().join("lib.rs"), None).unwrap_err();
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("`a` → `b` → `a`"), "{problems:?}");
    assert!(problems[0].contains("a.rs:2") && problems[0].contains("mod.rs:3"), "{problems:?}");
    // Without the back edge there is no circle, and the comment, the string and the test
    // module import nothing (c → a only).
    write_tree(dir.path(), &[("b/mod.rs", "pub mod inner;\npub struct X;\n")]);
    let graph = check(&dir.path().join("lib.rs"), None).unwrap();
    let edges: Vec<_> = graph.edges.keys().cloned().collect();
    let e = |a: &str, b: &str| (a.to_string(), b.to_string());
    assert_eq!(edges, vec![e("a", "b"), e("a", "b::inner"), e("c", "a")]);
}

#[test]
fn planted_circle_and_upward_import_in_arpa_core_are_named() {
    let src = workspace().join("arpa-core/src");
    let dir = tempfile::tempdir().unwrap();
    copy_dir(&src, dir.path());
    let root = dir.path().join("lib.rs");
    assert!(check(&root, Some(&CORE_LAYERS)).is_ok(), "the copy of arpa-core must pass before planting");
    // A circle inside one layer: the kernel imports the estimate, which imports the kernel.
    let kernel = dir.path().join("gather/kernel.rs");
    let text = std::fs::read_to_string(&kernel).unwrap();
    std::fs::write(&kernel, format!("{text}\n#[allow(unused_imports)]\nuse crate::gather::estimate::QueryPoint;\n")).unwrap();
    let problems = check(&root, Some(&CORE_LAYERS)).unwrap_err();
    assert!(problems.iter().any(|p| p.starts_with("import circle") && p.contains("`gather::estimate`") && p.contains("`gather::kernel`")), "{problems:?}");
    std::fs::write(&kernel, &text).unwrap();
    // An upward import: the rng (base) names the tracer trait (renderer layer).
    let rng = dir.path().join("base/rng.rs");
    let text = std::fs::read_to_string(&rng).unwrap();
    std::fs::write(&rng, format!("{text}\n#[allow(dead_code)]\nfn f(_: crate::render::tracer::Method) {{}}\n")).unwrap();
    let problems = check(&root, Some(&CORE_LAYERS)).unwrap_err();
    assert!(problems.iter().any(|p| p.contains("`base::rng` (base) imports `render::tracer` (renderer layer)")), "{problems:?}");
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}
