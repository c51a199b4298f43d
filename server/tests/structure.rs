//! The shape of the server's source: no circle among its modules, every SQL statement in `db`,
//! no production function over 150 lines, no file whose production part (before its
//! `#[cfg(test)]`) is over 1,000 lines.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_FUNCTION_LINES: usize = 150;
const MAX_FILE_LINES: usize = 1000;

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

/// Every source file but test modules (`tests.rs`), relative to `src`, with its production lines
/// (comments blanked).
fn production() -> Vec<(String, Vec<String>)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
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
            let rel = p.strip_prefix(&src).expect("under src").to_string_lossy().replace('\\', "/");
            (rel, lines)
        })
        .collect()
}

/// The top-level module a file belongs to (`routes/jobs.rs` → `routes`); `None` for `lib.rs`.
fn module_of(rel: &str) -> Option<String> {
    let first = rel.split('/').next()?;
    (first != "lib.rs").then(|| first.trim_end_matches(".rs").to_string())
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

#[test]
fn no_module_depends_on_a_module_that_depends_on_it() {
    let files = production();
    let modules: BTreeSet<String> = files.iter().filter_map(|(rel, _)| module_of(rel)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (rel, lines) in &files {
        let Some(from) = module_of(rel) else { continue };
        for to in lines.iter().flat_map(|l| crate_refs(l)) {
            // items re-exported at the root (`crate::Settings`) hide the module they come from
            assert!(modules.contains(&to), "{rel} names `crate::{to}`: name the module, not a re-export");
            if to != from {
                graph.entry(from.clone()).or_default().insert(to);
            }
        }
    }
    assert!(graph.get("dashboard").is_some_and(|d| d.contains("routes")), "the scan reads the imports: {graph:?}");
    // depth-first search for a back edge
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
    for m in graph.keys() {
        if let Some(circle) = visit(m, &graph, &mut done, &mut Vec::new()) {
            panic!("module circle: {}", circle.join(" → "));
        }
    }
}

#[test]
fn every_sql_statement_is_in_the_db_module() {
    for (rel, lines) in production() {
        if rel.starts_with("db/") {
            continue;
        }
        for (k, l) in lines.iter().enumerate() {
            assert!(
                !l.contains("sqlx::query") && !l.contains("QueryBuilder"),
                "{rel}:{}: SQL outside db: {}",
                k + 1,
                l.trim()
            );
        }
    }
}

#[test]
fn functions_and_files_stay_short() {
    let mut long = Vec::new();
    for (rel, lines) in production() {
        if lines.len() > MAX_FILE_LINES {
            long.push(format!("{rel}: {} lines before its tests", lines.len()));
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
                long.push(format!("{rel}:{}: a function of {end} lines: {}", k + 1, t));
            }
        }
    }
    assert!(long.is_empty(), "{}", long.join("\n"));
}
