//! The import graph, file by file: every `use` and every `crate::`/`super::`/`self::`
//! path in a library file's code (not its comments, not its `#[cfg(test)]` module) is
//! an arrow to the file that defines the module it names. A file may import only
//! downward, so the graph has no cycle, in `warpray` or in `simt`. A module's `mod`
//! declarations are not arrows, but its `use` and `pub use` of a child are: a hub that
//! re-exports a child while the child imports from the hub is a cycle.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One library source file and the module path it defines (`src/render/cis/mod.rs`
/// is `render::cis`).
struct SourceFile {
    path: PathBuf,
    module: Vec<String>,
    text: String,
}

/// The library files of the crate whose `src` is `src` (front ends excluded:
/// `main.rs` and `bin/` are crates of their own).
fn library_files(src: &Path) -> Vec<SourceFile> {
    let mut out = Vec::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let rel = path.strip_prefix(src).unwrap().to_path_buf();
            if path.is_dir() {
                if rel != Path::new("bin") {
                    stack.push(path);
                }
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") || rel == Path::new("main.rs") {
                continue;
            }
            let mut module: Vec<String> = rel.iter().map(|c| c.to_string_lossy().to_string()).collect();
            let last = module.pop().unwrap();
            if last != "lib.rs" && last != "mod.rs" {
                module.push(last.trim_end_matches(".rs").to_string());
            }
            out.push(SourceFile { text: std::fs::read_to_string(&path).unwrap(), path, module });
        }
    }
    out
}

/// The code of a file, line by line: comments blanked, and the `#[cfg(test)]` module
/// (tests sit above the code they test) left out.
fn code_lines(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut skip_depth: Option<i32> = None;
    let mut pending_test = false;
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("").to_string();
        if let Some(depth) = skip_depth.as_mut() {
            *depth += code.matches('{').count() as i32 - code.matches('}').count() as i32;
            if *depth <= 0 {
                skip_depth = None;
            }
            out.push(String::new());
            continue;
        }
        if code.trim() == "#[cfg(test)]" {
            pending_test = true;
            out.push(String::new());
            continue;
        }
        if pending_test && code.trim_start().starts_with("mod ") && code.contains('{') {
            let depth = code.matches('{').count() as i32 - code.matches('}').count() as i32;
            skip_depth = (depth > 0).then_some(depth);
            pending_test = false;
            out.push(String::new());
            continue;
        }
        pending_test = false;
        out.push(code);
    }
    out
}

/// Every path a `use` tree names (`a::{b, c::{d, e}}` gives `a::b`, `a::c::d`,
/// `a::c::e`), as segments.
fn use_paths(tree: &str) -> Vec<Vec<String>> {
    fn parse(prefix: &[String], s: &str, out: &mut Vec<Vec<String>>) {
        let s = s.trim();
        if let Some(open) = s.find('{') {
            let mut base = prefix.to_vec();
            base.extend(s[..open].split("::").map(str::trim).filter(|p| !p.is_empty()).map(String::from));
            let inner = &s[open + 1..s.rfind('}').unwrap_or(s.len())];
            let (mut depth, mut start) = (0, 0);
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        parse(&base, &inner[start..i], out);
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            parse(&base, &inner[start..], out);
        } else if !s.is_empty() {
            let s = s.split(" as ").next().unwrap();
            let mut path = prefix.to_vec();
            path.extend(s.split("::").map(str::trim).filter(|p| !p.is_empty() && *p != "*").map(String::from));
            out.push(path);
        }
    }
    let mut out = Vec::new();
    parse(&[], tree, &mut out);
    out
}

/// The module paths a file's code names, with the line, made absolute: `crate::`,
/// `super::`, `self::`, and a first segment that is one of the file's child modules.
fn named_modules(file: &SourceFile, modules: &BTreeSet<Vec<String>>) -> Vec<(usize, Vec<String>)> {
    let lines = code_lines(&file.text);
    let mut paths: Vec<(usize, Vec<String>)> = Vec::new();
    // `use` statements, which may span lines.
    let mut i = 0;
    while i < lines.len() {
        let t = lines[i].trim_start();
        let body = t.strip_prefix("pub use ").or_else(|| t.strip_prefix("pub(crate) use ")).or(t.strip_prefix("use "));
        if let Some(body) = body {
            let (start, mut text) = (i, body.to_string());
            while !text.contains(';') && i + 1 < lines.len() {
                i += 1;
                text.push_str(&lines[i]);
            }
            let tree = text.split(';').next().unwrap().to_string();
            paths.extend(use_paths(&tree).into_iter().map(|p| (start + 1, p)));
        }
        i += 1;
    }
    // Paths written inline.
    for (n, line) in lines.iter().enumerate() {
        let bytes = line.as_bytes();
        for root in ["crate::", "super::", "self::"] {
            let mut from = 0;
            while let Some(at) = line[from..].find(root).map(|a| a + from) {
                from = at + root.len();
                let prev = if at == 0 { b' ' } else { bytes[at - 1] };
                if prev.is_ascii_alphanumeric() || prev == b'_' || prev == b':' || prev == b'$' {
                    continue;
                }
                let rest: String =
                    line[at..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':').collect();
                paths.push((n + 1, rest.split("::").filter(|s| !s.is_empty()).map(String::from).collect()));
            }
        }
    }
    let mut out = Vec::new();
    for (line, path) in paths {
        let mut abs: Vec<String> = match path.first().map(String::as_str) {
            Some("crate") => path[1..].to_vec(),
            Some("self") => file.module.iter().cloned().chain(path[1..].iter().cloned()).collect(),
            Some("super") => {
                let mut base = file.module.clone();
                let mut k = 0;
                while path.get(k).is_some_and(|s| s == "super") {
                    base.pop();
                    k += 1;
                }
                base.into_iter().chain(path[k..].iter().cloned()).collect()
            }
            Some(first) => {
                let mut child = file.module.clone();
                child.push(first.to_string());
                if !modules.contains(&child) {
                    continue; // another crate, or an item in scope
                }
                file.module.iter().cloned().chain(path.iter().cloned()).collect()
            }
            None => continue,
        };
        // The longest prefix that is a module defined by a file.
        while !abs.is_empty() && !modules.contains(&abs) {
            abs.pop();
        }
        out.push((line, abs));
    }
    out
}

/// The graph's arrows: (from file's module, to file's module) with one line that
/// makes each.
fn arrows(files: &[SourceFile]) -> BTreeMap<(Vec<String>, Vec<String>), String> {
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| f.module.clone()).collect();
    let mut out = BTreeMap::new();
    for f in files {
        for (line, target) in named_modules(f, &modules) {
            if target != f.module {
                out.entry((f.module.clone(), target)).or_insert_with(|| format!("{}:{line}", f.path.display()));
            }
        }
    }
    out
}

/// The import cycles (strongly connected sets of two or more files), each as its
/// files' modules (sorted) and the arrows inside it.
fn cycles(files: &[SourceFile]) -> Vec<(Vec<String>, String)> {
    let arrows = arrows(files);
    let nodes: Vec<Vec<String>> = files.iter().map(|f| f.module.clone()).collect();
    let index: BTreeMap<&Vec<String>, usize> = nodes.iter().enumerate().map(|(i, m)| (m, i)).collect();
    let mut next: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    for (a, b) in arrows.keys() {
        next[index[a]].push(index[b]);
    }
    // Tarjan's strongly connected components, iteratively.
    let n = nodes.len();
    let (mut idx, mut low, mut on) = (vec![usize::MAX; n], vec![0; n], vec![false; n]);
    let (mut stack, mut counter, mut out) = (Vec::new(), 0, Vec::new());
    for root in 0..n {
        if idx[root] != usize::MAX {
            continue;
        }
        let mut work = vec![(root, 0usize)];
        while let Some(&mut (v, ref mut k)) = work.last_mut() {
            if *k == 0 && idx[v] == usize::MAX {
                idx[v] = counter;
                low[v] = counter;
                counter += 1;
                stack.push(v);
                on[v] = true;
            }
            if *k < next[v].len() {
                let w = next[v][*k];
                *k += 1;
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
                let mut component = Vec::new();
                while let Some(w) = stack.pop() {
                    on[w] = false;
                    component.push(w);
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    let set: BTreeSet<usize> = component.iter().copied().collect();
                    let inside: Vec<String> = arrows
                        .iter()
                        .filter(|((a, b), _)| set.contains(&index[a]) && set.contains(&index[b]))
                        .map(|((a, b), at)| format!("  {} -> {} ({at})", a.join("::"), b.join("::")))
                        .collect();
                    let mut members: Vec<String> = component.iter().map(|&w| nodes[w].join("::")).collect();
                    members.sort();
                    out.push((members, inside.join("\n")));
                }
            }
        }
    }
    out
}

/// Cycles that remain, each named by its files' modules (sorted, joined by spaces).
/// None: the last one, the scene hub re-exporting its children while they imported
/// from it, went when `Scene` moved to `scene/data.rs` and the loader to
/// `scene/load.rs`. The test fails on any cycle not listed, and on a listed one that
/// is gone, so the list only shrinks.
const KNOWN_CYCLES: &[&str] = &[];

#[test]
fn no_import_cycle_between_files() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = Vec::new();
    for (krate, src) in [("warpray", root.join("src")), ("simt", root.join("simt/src"))] {
        let files = library_files(&src);
        assert!(files.len() > 10, "only {} files under {}", files.len(), src.display());
        found.extend(cycles(&files).into_iter().map(|c| (krate, c)));
    }
    let names: Vec<String> = found.iter().map(|(k, (members, _))| format!("{k}: {}", members.join(" "))).collect();
    let new: Vec<String> = found
        .iter()
        .zip(&names)
        .filter(|(_, n)| !KNOWN_CYCLES.contains(&n.as_str()))
        .map(|((_, (_, text)), n)| format!("{n}\n{text}"))
        .collect();
    assert!(new.is_empty(), "import cycles:\n{}", new.join("\n"));
    let gone: Vec<&&str> = KNOWN_CYCLES.iter().filter(|k| !names.iter().any(|n| n == **k)).collect();
    assert!(gone.is_empty(), "these cycles are gone: take them off KNOWN_CYCLES: {gone:?}");
}

#[test]
fn the_cycle_check_sees_a_planted_cycle() {
    // Three files where a child imports from its hub and the hub re-exports the child,
    // as `render/` did: the check must name the cycle. A `mod` line alone, a test
    // module and a comment are not arrows.
    let file = |path: &str, module: &[&str], text: &str| SourceFile {
        path: PathBuf::from(path),
        module: module.iter().map(|s| s.to_string()).collect(),
        text: text.to_string(),
    };
    let hub = file("render/mod.rs", &["render"], "mod walk;\nmod options;\npub struct Context;\n");
    let walk = file(
        "render/walk.rs",
        &["render", "walk"],
        "use super::options::Opts; // crate::render::Context\n#[cfg(test)]\nmod tests {\n    use crate::render::Context;\n}\n",
    );
    let options = file("render/options.rs", &["render", "options"], "pub struct Opts;\n");
    let clean = [hub, walk, options];
    assert!(cycles(&clean).is_empty(), "{:?}", cycles(&clean));
    let [hub, walk, options] = clean;
    let hub = SourceFile { text: hub.text + "pub use walk::step;\n", ..hub };
    let walk = SourceFile { text: walk.text + "fn f(c: &crate::render::Context) {}\n", ..walk };
    let found = cycles(&[hub, walk, options]);
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].0, ["render", "render::walk"]);
    assert!(
        found[0].1.contains("render -> render::walk") && found[0].1.contains("render::walk -> render"),
        "{found:?}"
    );
    // Grouped and nested `use` trees name every path.
    let paths = use_paths("crate::{a::X, b::{c::Y, d}, e as f}");
    let joined: Vec<String> = paths.iter().map(|p| p.join("::")).collect();
    assert_eq!(joined, ["crate::a::X", "crate::b::c::Y", "crate::b::d", "crate::e"]);
}
