//! The module layering of ARCHITECTURE.md ("Layers"), checked on the source: every
//! `crate::m` a module names outside comments is a module of a lower layer. A new import that
//! runs upwards or sideways (and so could close a circle) fails here with the line that makes it.

use std::path::Path;

/// Top-level modules by layer, lowest first; a module may use only modules of lower layers.
const LAYERS: &[&[&str]] = &[
    &["simd", "rng", "memory", "slots", "error"],
    &["geometry"],
    &["files", "encoding", "mlp"],
    &["data", "field"],
    &["render", "eval"],
    &["train"],
    &["io"],
    &["onboard", "compare"],
    &["bench", "cli"],
    &["app"],
];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src is readable") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn imports_run_down_the_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut wrong = Vec::new();
    let mut checked = 0;
    for path in &files {
        let rel = path.strip_prefix(&src).expect("under src");
        let top = rel.iter().next().and_then(|c| c.to_str()).expect("a file name").trim_end_matches(".rs");
        if top == "lib" || top == "bin" {
            continue;
        }
        let own = layer(top).unwrap_or_else(|| panic!("src/{top}: add the module to LAYERS"));
        let text = std::fs::read_to_string(path).expect("a source file");
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            for (at, _) in code.match_indices("crate::") {
                let name: String = code[at + 7..].chars().take_while(|c| c.is_ascii_lowercase() || *c == '_').collect();
                if name.is_empty() || name == top {
                    continue; // crate-root items (`crate::GradientMode`) and the module itself
                }
                checked += 1;
                match layer(&name) {
                    Some(l) if l < own => {}
                    _ => wrong.push(format!("src/{}:{}: {top} uses crate::{name}", rel.display(), n + 1)),
                }
            }
        }
    }
    assert!(checked > 100, "only {checked} imports found: the scan is broken");
    assert!(wrong.is_empty(), "imports against the layers:\n{}", wrong.join("\n"));
}
