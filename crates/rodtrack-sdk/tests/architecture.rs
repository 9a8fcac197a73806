//! `docs/ARCHITECTURE.md` matches the tree: every crate of `crates/` and every other
//! workspace member (the Python package in `python/`) has a row in its table,
//! each row's "depends on" column names exactly the rodtrack crates its Cargo.toml depends on,
//! and none of those is in its "may not depend on" column.

#![allow(clippy::unwrap_used)]

use std::collections::BTreeSet;
use std::path::Path;

const SHORT: [&str; 9] = [
    "core", "io", "sim", "sdk", "print", "eval", "console", "video", "genicam",
];

fn names_in(text: &str) -> BTreeSet<String> {
    text.split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| SHORT.contains(w))
        .map(|w| w.to_string())
        .collect()
}

/// The rodtrack crates in `[dependencies]` of a Cargo.toml, by short name.
fn deps_of(manifest: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(manifest).unwrap();
    let mut in_deps = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            in_deps = t == "[dependencies]";
            continue;
        }
        if let (true, Some(rest)) = (in_deps, t.strip_prefix("rodtrack-")) {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric())
                .collect();
            out.insert(name);
        }
    }
    out
}

/// The workspace members of the root Cargo.toml that are not under `crates/`.
fn members_outside_crates(root: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let start = text.find("members = [").unwrap();
    let list = &text[start..start + text[start..].find(']').unwrap()];
    list.lines()
        .filter_map(|l| l.trim().strip_prefix('"')?.split('"').next())
        .filter(|m| !m.starts_with("crates/"))
        .map(str::to_string)
        .collect()
}

/// The `name` of a Cargo.toml's `[package]`.
fn package_name(manifest: &Path) -> String {
    let text = std::fs::read_to_string(manifest).unwrap();
    text.lines()
        .find_map(|l| l.trim().strip_prefix("name = \""))
        .and_then(|rest| rest.split('"').next())
        .unwrap()
        .to_string()
}

#[test]
fn the_architecture_table_matches_the_crates() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let doc = std::fs::read_to_string(root.join("docs/ARCHITECTURE.md")).unwrap();
    let mut rows = std::collections::BTreeMap::new();
    for line in doc.lines().filter(|l| l.starts_with("| `rodtrack")) {
        let cols: Vec<&str> = line.split('|').map(str::trim).collect();
        let name = cols[1].split('`').nth(1).unwrap().to_string();
        rows.insert(name, (cols[3].to_string(), cols[4].to_string()));
    }
    let mut crates = 0;
    let mut manifests: Vec<std::path::PathBuf> = std::fs::read_dir(root.join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path().join("Cargo.toml"))
        .collect();
    manifests.extend(
        members_outside_crates(&root)
            .iter()
            .map(|m| root.join(m).join("Cargo.toml")),
    );
    for manifest in manifests {
        if !manifest.exists() {
            continue;
        }
        crates += 1;
        let name = package_name(&manifest);
        let (depends, forbidden) = rows
            .get(&name)
            .unwrap_or_else(|| panic!("{name} has no row in docs/ARCHITECTURE.md"));
        let deps = deps_of(&manifest);
        if !depends.contains("all of the above") {
            assert_eq!(
                &names_in(depends),
                &deps,
                "{name}: the \"depends on\" column"
            );
        }
        let bad: Vec<_> = names_in(forbidden).intersection(&deps).cloned().collect();
        assert!(
            bad.is_empty(),
            "{name} depends on {bad:?}, which its row forbids"
        );
    }
    assert!(crates >= 11, "{crates} crates found");
}
