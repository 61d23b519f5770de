//! The crate's metadata: a `rust-version` no lower than any locked dependency needs,
//! and the licence files the `license` field names.

use std::process::Command;

/// `(major, minor)` of a `rust-version` string (`1.95` or `1.95.0`).
fn version(v: &str) -> (u32, u32) {
    let mut parts = v.split('.').map(|p| p.parse::<u32>().unwrap_or(0));
    (parts.next().unwrap_or(0), parts.next().unwrap_or(0))
}

#[test]
fn rust_version_covers_every_locked_dependency() {
    // The host's packages with every feature of ours: what a build here downloads, so
    // this works offline (other platforms' crates may never have been fetched).
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let verbose = Command::new(&rustc).arg("-vV").output().expect("rustc -vV");
    let verbose = String::from_utf8_lossy(&verbose.stdout).to_string();
    let host = verbose.lines().find_map(|l| l.strip_prefix("host: ")).expect("a host line").to_string();
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--offline", "--locked", "--features", "inspector,cuda"])
        .args(["--filter-platform", &host])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(out.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&out.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let packages = meta["packages"].as_array().unwrap();
    let ours = packages.iter().find(|p| p["name"] == "warpray").unwrap()["rust_version"].as_str().unwrap().to_string();
    let mut needs: Vec<((u32, u32), String)> = packages
        .iter()
        .filter_map(|p| Some((version(p["rust_version"].as_str()?), format!("{} {}", p["name"], p["version"]))))
        .collect();
    needs.sort();
    let (newest, who) = needs.last().cloned().unwrap();
    assert!(
        version(&ours) >= newest,
        "rust-version = {ours} but {who} needs {}.{}: raise it in the workspace Cargo.toml",
        newest.0,
        newest.1
    );
    // And the compiler building this test is new enough for what we declare.
    let release = verbose.lines().find_map(|l| l.strip_prefix("release: ")).expect("a release line");
    assert!(version(release) >= version(&ours), "rustc {release} is older than rust-version {ours}");
}

#[test]
fn licence_files_match_the_license_field() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    assert!(manifest.contains(r#"license = "MIT OR Apache-2.0""#));
    for dir in [root.to_path_buf(), root.join("simt")] {
        let mit = std::fs::read_to_string(dir.join("LICENSE-MIT")).unwrap();
        let apache = std::fs::read_to_string(dir.join("LICENSE-APACHE")).unwrap();
        assert!(mit.contains("Permission is hereby granted") && apache.contains("Apache License"));
    }
}
