//! Record the versions of the key crates (from Cargo.lock) so `genplan info` can print them.
use std::fs;

fn main() {
    let lock_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../Cargo.lock");
    println!("cargo:rerun-if-changed={lock_path}");
    let lock = fs::read_to_string(lock_path).unwrap_or_default();
    let mut found = Vec::new();
    let mut name: Option<String> = None;
    for line in lock.lines() {
        if let Some(n) = line.strip_prefix("name = ") {
            name = Some(n.trim_matches('"').to_string());
        } else if let (Some(v), Some(n)) = (line.strip_prefix("version = "), name.as_ref()) {
            if ["nalgebra", "parry3d-f64", "pyo3", "numpy", "rayon"].contains(&n.as_str()) {
                found.push(format!("{}={}", n, v.trim_matches('"')));
            }
            name = None;
        }
    }
    println!("cargo:rustc-env=GENPLAN_CRATE_VERSIONS={}", found.join(","));
}
