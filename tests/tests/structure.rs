//! The shape of every crate's source in the workspace: no production function over 150 lines,
//! no file whose production part (before its `#[cfg(test)]`) is over 1,000 lines, and no circle
//! among a crate's top-level modules. The crates are the workspace's members with a `src`
//! directory. The server adds its own rule: every SQL statement is in its `db` module.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_FUNCTION_LINES: usize = 150;
const MAX_FILE_LINES: usize = 1000;

/// The workspace's members (from `members = [...]` of its manifest) that have a `src`
/// directory, by name.
fn crates() -> Vec<(String, PathBuf)> {
    let root = cryofit_tests::workspace();
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).expect("workspace manifest");
    let start = manifest.find("members").expect("a members list");
    let list = &manifest[start..];
    let list = &list[list.find('[').expect("[")..=list.find(']').expect("]")];
    let members: Vec<String> = list.split('"').skip(1).step_by(2).map(str::to_string).collect();
    assert!(members.len() >= 7, "the members list is read: {members:?}");
    members.into_iter().map(|m| (m.clone(), root.join(&m).join("src"))).filter(|(_, src)| src.is_dir()).collect()
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("source directory") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every source file of `src` but test modules (`tests.rs`), relative to `src`, with its
/// production lines (comments blanked).
fn production(src: &Path) -> Vec<(String, Vec<String>)> {
    let mut files = Vec::new();
    sources(src, &mut files);
    files.retain(|p| p.file_name().is_none_or(|n| n != "tests.rs"));
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).expect("source");
            let lines = text
                .lines()
                .take_while(|l| l.trim() != "#[cfg(test)]")
                .map(|l| if l.trim_start().starts_with("//") { String::new() } else { l.to_string() })
                .collect();
            let rel = p.strip_prefix(src).expect("under src").to_string_lossy().replace('\\', "/");
            (rel, lines)
        })
        .collect()
}

/// The top-level module a file belongs to (`routes/jobs.rs` → `routes`); `None` for a crate
/// root (`lib.rs`, `main.rs`, `bin/…`).
fn module_of(rel: &str) -> Option<String> {
    let first = rel.split('/').next()?;
    (!["lib.rs", "main.rs", "bin"].contains(&first)).then(|| first.trim_end_matches(".rs").to_string())
}

/// The top-level modules a line names as `crate::a` or `crate::{a, b::c}`.
fn crate_refs(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (at, _) in line.match_indices("crate::") {
        if line[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_') {
            continue; // `mycrate::`
        }
        let rest = &line[at + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = group.split('}').next().unwrap_or("");
            for item in inner.split(',') {
                let name: String = item.trim().chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                if !name.is_empty() {
                    out.push(name);
                }
            }
        } else {
            let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if !name.is_empty() {
                out.push(name);
            }
        }
    }
    out
}

/// The names of the items a crate root's production `lines` define (not those it re-exports).
fn root_items(lines: &[String]) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for l in lines.iter().filter(|l| !l.starts_with(' ')) {
        let t = l.trim_start_matches("pub(crate) ").trim_start_matches("pub ").trim_start_matches("async ");
        let kinds = ["struct ", "enum ", "union ", "trait ", "type ", "const ", "static ", "fn ", "macro_rules! "];
        if let Some(rest) = kinds.iter().find_map(|k| t.strip_prefix(k)) {
            out.insert(rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect());
        }
    }
    out
}

/// The crate's module graph: which top-level modules each one names. A module may name an item
/// the crate root defines (the root is not a module of the graph), not one it re-exports.
fn module_graph(name: &str, files: &[(String, Vec<String>)]) -> BTreeMap<String, BTreeSet<String>> {
    let modules: BTreeSet<String> = files.iter().filter_map(|(rel, _)| module_of(rel)).collect();
    let roots: BTreeSet<String> =
        files.iter().filter(|(rel, _)| module_of(rel).is_none()).flat_map(|(_, lines)| root_items(lines)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (rel, lines) in files {
        let Some(from) = module_of(rel) else { continue };
        for to in lines.iter().flat_map(|l| crate_refs(l)) {
            if !modules.contains(&to) {
                // items re-exported at the root (`crate::Settings`) hide the module they come from
                assert!(roots.contains(&to), "{name}/src/{rel} names `crate::{to}`: name the module, not a re-export");
                continue;
            }
            if to != from {
                graph.entry(from.clone()).or_default().insert(to);
            }
        }
    }
    graph
}

/// A circle in `graph`, as the modules along it, if there is one (depth-first search for a
/// back edge).
fn circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        done: &mut BTreeSet<String>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = path.iter().position(|p| p == m) {
            let mut circle = path[k..].to_vec();
            circle.push(m.to_string());
            return Some(circle);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.to_string());
        for next in graph.get(m).into_iter().flatten() {
            if let Some(c) = visit(next, graph, done, path) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph.keys().find_map(|m| visit(m, graph, &mut done, &mut Vec::new()))
}

#[test]
fn no_module_depends_on_a_module_that_depends_on_it() {
    let mut circles = Vec::new();
    let mut graphs = BTreeMap::new();
    for (name, src) in crates() {
        let graph = module_graph(&name, &production(&src));
        // every circle: each one found is cut at its last edge before looking for the next
        let mut cut = graph.clone();
        while let Some(c) = circle(&cut) {
            circles.push(format!("{name}: {}", c.join(" → ")));
            let (from, to) = (&c[c.len() - 2], &c[c.len() - 1]);
            cut.get_mut(from).expect("an edge of the circle").remove(to);
        }
        graphs.insert(name, graph);
    }
    // the scan reads the imports
    for (krate, from, to) in [("solver", "driver", "scheme"), ("server", "dashboard", "routes")] {
        assert!(
            graphs.get(krate).and_then(|g| g.get(from)).is_some_and(|d| d.contains(to)),
            "{krate}: {from} → {to} not found: {:?}",
            graphs.get(krate)
        );
    }
    assert!(circles.is_empty(), "module circles:\n{}", circles.join("\n"));
}

#[test]
fn functions_and_files_stay_short() {
    let mut long = Vec::new();
    let mut files = 0;
    for (name, src) in crates() {
        for (rel, lines) in production(&src) {
            files += 1;
            if lines.len() > MAX_FILE_LINES {
                long.push(format!("{name}/src/{rel}: {} lines before its tests", lines.len()));
            }
            for (k, l) in lines.iter().enumerate() {
                let t = l.trim_start();
                let is_fn = ["fn ", "pub fn ", "async fn ", "pub async fn ", "pub(crate) fn ", "pub(crate) async fn "]
                    .iter()
                    .chain(&["pub(super) fn ", "pub(super) async fn ", "const fn ", "pub const fn "])
                    .any(|p| t.starts_with(p));
                if !is_fn || t.ends_with(';') {
                    continue;
                }
                let indent = l.len() - t.len();
                let close = format!("{}}}", " ".repeat(indent));
                let end = lines[k..].iter().position(|x| x.trim_end() == close).map_or(lines.len() - k, |n| n + 1);
                if end > MAX_FUNCTION_LINES {
                    long.push(format!("{name}/src/{rel}:{}: a function of {end} lines: {}", k + 1, t));
                }
            }
        }
    }
    assert!(files > 100, "the scan reads the sources: {files} files");
    assert!(long.is_empty(), "{}", long.join("\n"));
}

#[test]
fn every_sql_statement_of_the_server_is_in_its_db_module() {
    let (_, src) = crates().into_iter().find(|(name, _)| name == "server").expect("the server crate");
    let files = production(&src);
    assert!(files.iter().any(|(rel, _)| rel.starts_with("db/")), "the scan reads server/src/db");
    let mut outside = Vec::new();
    for (rel, lines) in files.iter().filter(|(rel, _)| !rel.starts_with("db/")) {
        for (k, l) in lines.iter().enumerate() {
            if l.contains("sqlx::query") || l.contains("QueryBuilder") {
                outside.push(format!("server/src/{rel}:{}: {}", k + 1, l.trim()));
            }
        }
    }
    assert!(outside.is_empty(), "SQL outside server/src/db:\n{}", outside.join("\n"));
}
