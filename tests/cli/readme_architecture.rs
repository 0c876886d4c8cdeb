//! The README's architecture table says which workspace crates each crate uses; this test
//! holds it to `cargo metadata`: every workspace member has exactly one row, and the row's
//! "uses" column lists exactly the member's normal (not dev, not build) dependencies on
//! other workspace crates.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

type Uses = BTreeMap<String, BTreeSet<String>>;

/// Each workspace member and the workspace crates it depends on (normal dependencies), as
/// `cargo metadata --format-version 1 --no-deps` reports them.
fn workspace_uses(metadata: &serde_json::Value) -> Uses {
    let packages = metadata["packages"]
        .as_array()
        .expect("metadata has packages");
    let members: BTreeSet<String> = packages
        .iter()
        .map(|p| p["name"].as_str().expect("package name").to_string())
        .collect();
    packages
        .iter()
        .map(|p| {
            let uses = p["dependencies"]
                .as_array()
                .expect("package dependencies")
                .iter()
                .filter(|d| d["kind"].is_null())
                .map(|d| d["name"].as_str().expect("dependency name").to_string())
                .filter(|name| members.contains(name))
                .collect();
            (p["name"].as_str().unwrap().to_string(), uses)
        })
        .collect()
}

/// The cells of a Markdown table row (`| a | b |`), trimmed; `\|` inside a cell is kept.
fn cells(line: &str) -> Vec<String> {
    let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
    let mut out = vec![String::new()];
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                out.last_mut().unwrap().push('|');
                chars.next();
            }
            '|' => out.push(String::new()),
            _ => out.last_mut().unwrap().push(c),
        }
    }
    out.into_iter().map(|c| c.trim().to_string()).collect()
}

/// A crate name written as `name` in a cell.
fn crate_name(cell: &str) -> Result<String, String> {
    let name = cell.trim();
    match name.strip_prefix('`').and_then(|n| n.strip_suffix('`')) {
        Some(n) if !n.is_empty() && !n.contains('`') => Ok(n.to_string()),
        _ => Err(format!("`{cell}` is not a crate name in backticks")),
    }
}

/// The rows of the table under `## Architecture`: crate -> the crates its "uses" column
/// lists ("—" for none). Errors name the line.
fn readme_uses(readme: &str) -> Result<Uses, Vec<String>> {
    let mut lines = readme
        .lines()
        .enumerate()
        .skip_while(|(_, l)| l.trim() != "## Architecture")
        .skip(1)
        .take_while(|(_, l)| !l.starts_with("## "))
        .skip_while(|(_, l)| !l.trim_start().starts_with('|'));
    let (_, header) = lines.next().ok_or(vec![
        "README.md: no table under `## Architecture`".to_string()
    ])?;
    let header = cells(header);
    let col = |name: &str| header.iter().position(|h| h == name);
    let (Some(crate_col), Some(uses_col)) = (col("crate"), col("uses")) else {
        return Err(vec![format!(
            "README.md: the architecture table's header {header:?} needs columns \"crate\" and \"uses\""
        )]);
    };
    let mut rows = Uses::new();
    let mut errors = Vec::new();
    for (i, line) in lines
        .skip(1) // |---|---|
        .take_while(|(_, l)| l.trim_start().starts_with('|'))
    {
        let at = format!("README.md:{}", i + 1);
        let row = cells(line);
        if row.len() != header.len() {
            errors.push(format!(
                "{at}: {} cells, the header has {}",
                row.len(),
                header.len()
            ));
            continue;
        }
        let name = match crate_name(&row[crate_col]) {
            Ok(n) => n,
            Err(e) => {
                errors.push(format!("{at}: {e}"));
                continue;
            }
        };
        let uses_cell = row[uses_col].as_str();
        let mut uses = BTreeSet::new();
        if uses_cell != "—" {
            for item in uses_cell.split(',') {
                match crate_name(item) {
                    Ok(n) => {
                        if !uses.insert(n.clone()) {
                            errors.push(format!("{at}: `{name}` lists `{n}` twice"));
                        }
                    }
                    Err(e) => {
                        errors.push(format!("{at}: uses of `{name}`: {e} (write — for none)"))
                    }
                }
            }
        }
        if rows.insert(name.clone(), uses).is_some() {
            errors.push(format!("{at}: a second row for `{name}`"));
        }
    }
    if errors.is_empty() {
        Ok(rows)
    } else {
        Err(errors)
    }
}

/// Every difference between the README's table and the workspace; empty when they agree.
fn differences(readme: &str, actual: &Uses) -> Vec<String> {
    let table = match readme_uses(readme) {
        Ok(t) => t,
        Err(e) => return e,
    };
    let list = |s: &BTreeSet<String>| {
        if s.is_empty() {
            "—".to_string()
        } else {
            s.iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    let mut out = Vec::new();
    for (name, uses) in actual {
        match table.get(name) {
            None => out.push(format!(
                "README.md: the architecture table has no row for `{name}` (uses: {})",
                list(uses)
            )),
            Some(listed) if listed != uses => out.push(format!(
                "README.md: `{name}` uses {} (cargo metadata), the table says {}",
                list(uses),
                list(listed)
            )),
            Some(_) => {}
        }
    }
    for name in table.keys().filter(|n| !actual.contains_key(*n)) {
        out.push(format!(
            "README.md: the architecture table lists `{name}`, which is not a workspace member"
        ));
    }
    out
}

fn metadata() -> serde_json::Value {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| env!("CARGO").into());
    let output = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--manifest-path",
        ])
        .arg(root.join("Cargo.toml"))
        .output()
        .expect("run cargo metadata");
    assert!(
        output.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("cargo metadata prints JSON")
}

fn readme() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_readme_architecture_table_matches_cargo_metadata() {
    let actual = workspace_uses(&metadata());
    assert!(
        actual.len() > 1,
        "cargo metadata lists the workspace: {actual:?}"
    );
    let diff = differences(&readme(), &actual);
    assert!(diff.is_empty(), "\n{}\n", diff.join("\n"));
}

/// The check itself can fail: a row with a crate missing, one too many, or a row gone.
#[test]
fn a_wrong_row_in_the_architecture_table_is_reported() {
    let actual = workspace_uses(&metadata());
    let readme = readme();
    let row = readme
        .lines()
        .find(|l| l.starts_with("| `waam-planner` |"))
        .expect("a row for waam-planner");
    let dropped = row.replacen("`waam-access`, ", "", 1);
    assert_ne!(dropped, row);
    let diff = differences(&readme.replacen(row, &dropped, 1), &actual);
    assert!(
        diff.len() == 1 && diff[0].contains("`waam-planner` uses"),
        "{diff:?}"
    );
    let added = row.replacen("`waam-thermal` |", "`waam-thermal`, `waam-plot` |", 1);
    assert_ne!(added, row);
    assert_eq!(
        differences(&readme.replacen(row, &added, 1), &actual).len(),
        1
    );
    let gone = differences(&readme.replacen(&format!("{row}\n"), "", 1), &actual);
    assert!(
        gone.len() == 1 && gone[0].contains("no row for `waam-planner`"),
        "{gone:?}"
    );
}
