//! The module graph reads one way: no import cycle among the top-level modules of `src`, nor
//! among the children of any one module. A module may use what its ancestors define (a parent
//! owns the types its children share); every other `crate::` or `super::` path is an edge from
//! the module that writes it to the module it names, and the graph of those edges, taken level
//! by level, must have no cycle. CONTRIBUTING.md's module map is the intended order.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

type Module = Vec<String>;

/// Every module of `src` (by its path: `["train", "step"]`) and its source, without comments
/// and without its `#[cfg(test)] mod tests` block.
fn modules() -> BTreeMap<Module, String> {
    fn walk(dir: &Path, root: &Path, out: &mut BTreeMap<Module, String>) {
        for entry in std::fs::read_dir(dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                walk(&path, root, out);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let rel = path.strip_prefix(root).unwrap().with_extension("");
            let mut module: Module = rel.iter().map(|s| s.to_string_lossy().into()).collect();
            if module.last().is_some_and(|m| m == "mod") {
                module.pop();
            }
            if module == ["lib"] || module == ["main"] {
                module.clear();
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let code = text.split("#[cfg(test)]\nmod tests").next().unwrap();
            let code: String = code
                .lines()
                .map(|l| l.split("//").next().unwrap())
                .collect::<Vec<_>>()
                .join("\n");
            out.insert(module, code);
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = BTreeMap::new();
    walk(&root, &root, &mut out);
    out
}

/// The paths a use tree starting at `text` names: `a::{b, c::{d, e}}` gives `a::b`, `a::c::d`
/// and `a::c::e` (a prefix of each is enough to find its module).
fn use_paths(text: &str) -> Vec<Vec<String>> {
    fn tree(chars: &[char], at: &mut usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
        let mut path = prefix;
        loop {
            let start = *at;
            while *at < chars.len() && (chars[*at].is_alphanumeric() || chars[*at] == '_') {
                *at += 1;
            }
            if *at > start {
                path.push(chars[start..*at].iter().collect());
            }
            if chars[*at..].starts_with(&[':', ':']) {
                *at += 2;
                if chars.get(*at) == Some(&'{') {
                    *at += 1;
                    loop {
                        while chars
                            .get(*at)
                            .is_some_and(|c| c.is_whitespace() || *c == ',')
                        {
                            *at += 1;
                        }
                        if chars.get(*at).is_none_or(|c| *c == '}') {
                            *at += 1;
                            return;
                        }
                        tree(chars, at, path.clone(), out);
                    }
                }
                continue;
            }
            out.push(path);
            return;
        }
    }
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    tree(&chars, &mut 0, Vec::new(), &mut out);
    out
}

/// Edges `(from, to)`: a module naming another (not itself, not an ancestor).
fn edges(modules: &BTreeMap<Module, String>) -> BTreeSet<(Module, Module)> {
    let mut edges = BTreeSet::new();
    for (module, code) in modules {
        for base in ["crate::", "super::"] {
            for (i, _) in code.match_indices(base) {
                let before = code[..i].chars().last();
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    continue;
                }
                for path in use_paths(&code[i..]) {
                    let mut target: Module = module.clone();
                    let mut rest = &path[..];
                    if rest.first().is_some_and(|s| s == "crate") {
                        target.clear();
                        rest = &rest[1..];
                    } else {
                        // `super` in a file module is its parent.
                        while rest.first().is_some_and(|s| s == "super") {
                            target.pop();
                            rest = &rest[1..];
                        }
                    }
                    target.extend(rest.iter().cloned());
                    let named = (0..=target.len())
                        .rev()
                        .map(|k| target[..k].to_vec())
                        .find(|m| modules.contains_key(m))
                        .unwrap();
                    if !module.starts_with(&named) {
                        edges.insert((module.clone(), named));
                    }
                }
            }
        }
    }
    edges
}

/// A cycle among the children of `parent`, if there is one, as the children's names.
fn cycle_under(parent: &Module, edges: &BTreeSet<(Module, Module)>) -> Option<Vec<String>> {
    let n = parent.len();
    let mut graph: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for (a, b) in edges {
        let under = a.len() > n && b.len() > n && a.starts_with(parent) && b.starts_with(parent);
        if under && a[n] != b[n] {
            graph.entry(&a[n]).or_default().insert(&b[n]);
        }
    }
    // Depth-first search; a node met again while on the stack closes a cycle.
    fn visit<'a>(
        node: &'a str,
        graph: &BTreeMap<&'a str, BTreeSet<&'a str>>,
        stack: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<String>> {
        if let Some(at) = stack.iter().position(|s| *s == node) {
            return Some(stack[at..].iter().map(|s| s.to_string()).collect());
        }
        if !done.insert(node) {
            return None;
        }
        stack.push(node);
        for next in graph.get(node).into_iter().flatten() {
            if let Some(cycle) = visit(next, graph, stack, done) {
                return Some(cycle);
            }
        }
        stack.pop();
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|node| visit(node, &graph, &mut Vec::new(), &mut done))
}

#[test]
fn use_trees_are_read_whole() {
    let got = use_paths("crate::a::{b, c::{d, e}, f};");
    let want = [vec!["crate", "a", "b"], ["crate", "a", "c", "d"].to_vec()];
    assert_eq!(&got[..2], &want);
    assert_eq!(got.len(), 4, "{got:?}");
    assert_eq!(use_paths("super::super::x(1)"), [["super", "super", "x"]]);
}

#[test]
fn a_cycle_is_found() {
    let m = |s: &str| -> Module { s.split("::").map(String::from).collect() };
    let edges: BTreeSet<_> = [("a", "b::x"), ("b::y", "c"), ("c", "a")]
        .into_iter()
        .map(|(a, b)| (m(a), m(b)))
        .collect();
    assert_eq!(cycle_under(&Vec::new(), &edges).map(|c| c.len()), Some(3));
    let one_way: BTreeSet<_> = edges.into_iter().filter(|(a, _)| a != &m("c")).collect();
    assert_eq!(cycle_under(&Vec::new(), &one_way), None);
}

#[test]
fn modules_import_one_way() {
    let modules = modules();
    assert!(modules.contains_key(&vec!["train".to_string(), "step".to_string()]));
    let edges = edges(&modules);
    assert!(
        edges.contains(&(vec!["train".into()], vec!["critic".into()])),
        "the scan sees `use crate::critic::...` in train"
    );
    let parents: BTreeSet<Module> = modules
        .keys()
        .flat_map(|m| (0..m.len()).map(|k| m[..k].to_vec()))
        .collect();
    let cycles: Vec<String> = parents
        .iter()
        .filter_map(|p| cycle_under(p, &edges).map(|c| format!("under {p:?}: {c:?}")))
        .collect();
    assert!(cycles.is_empty(), "import cycles: {cycles:#?}");
}
