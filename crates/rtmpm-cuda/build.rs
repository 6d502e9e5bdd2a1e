//! The kernel list, from one place: the `kernels/` folder. Every `.cu` and `.cuh` file is embedded
//! (`SOURCES`), every `.cu` file is a translation unit of the one NVRTC program (`UNITS`), and
//! every `extern "C" __global__` function becomes a variant of the `Kernel` enum, which the host
//! loads by name (`src/kernels.rs`) and the NVRTC compile test checks in the PTX. Adding a kernel
//! is writing it; nothing else lists it.

use std::fmt::Write;
use std::path::{Path, PathBuf};

fn files(dir: &Path, rel: &str, out: &mut Vec<(String, PathBuf)>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        let name = p
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default()
            .to_string();
        let rel_name = if rel.is_empty() {
            name.clone()
        } else {
            format!("{rel}/{name}")
        };
        if p.is_dir() {
            files(&p, &rel_name, out);
        } else if name.ends_with(".cu") || name.ends_with(".cuh") {
            out.push((rel_name, p));
        }
    }
}

/// Names of the `extern "C" __global__` functions of a source (the identifier before the first
/// `(` after `void`, skipping `__launch_bounds__(...)`).
fn entry_points(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let t = line.trim_start();
        let Some(rest) = t.strip_prefix("extern \"C\" __global__ ") else {
            continue;
        };
        let Some(rest) = rest.trim_start().strip_prefix("void ") else {
            continue;
        };
        let mut rest = rest.trim_start();
        if let Some(r) = rest.strip_prefix("__launch_bounds__(") {
            let close = r.find(')').unwrap_or(0);
            rest = r[close + 1..].trim_start();
        }
        let name: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        if !name.is_empty() {
            out.push(name);
        }
    }
    out
}

fn camel(name: &str) -> String {
    name.split('_')
        .map(|w| {
            let mut c = w.chars();
            match c.next() {
                Some(f) => f.to_ascii_uppercase().to_string() + c.as_str(),
                None => String::new(),
            }
        })
        .collect()
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let dir = root.join("kernels");
    println!("cargo:rerun-if-changed=kernels");
    let mut all = Vec::new();
    files(&dir, "", &mut all);
    let mut code = String::new();
    code.push_str(
        "/// Every kernel source file, by path relative to `kernels/` (embedded at build time).\n",
    );
    code.push_str("pub const SOURCES: &[(&str, &str)] = &[\n");
    for (rel, path) in &all {
        println!("cargo:rerun-if-changed={}", path.display());
        let _ = writeln!(
            code,
            "    ({rel:?}, include_str!({:?})),",
            path.display().to_string()
        );
    }
    code.push_str("];\n\n");
    code.push_str("/// The translation units of the one NVRTC program: every `.cu` file.\n");
    code.push_str("pub const UNITS: &[&str] = &[\n");
    let mut kernels: Vec<(String, String)> = Vec::new();
    for (rel, path) in &all {
        if rel.ends_with(".cu") {
            let _ = writeln!(code, "    {rel:?},");
            let text = std::fs::read_to_string(path).unwrap_or_default();
            for k in entry_points(&text) {
                kernels.push((k, rel.clone()));
            }
        }
    }
    code.push_str("];\n\n");
    code.push_str("/// Every kernel entry point of the program (`extern \"C\" __global__`).\n");
    code.push_str("#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]\npub enum Kernel {\n");
    for (k, file) in &kernels {
        let _ = writeln!(code, "    /// `{k}` (kernels/{file})\n    {},", camel(k));
    }
    code.push_str("}\n\nimpl Kernel {\n    /// Every kernel, in source order.\n    pub const ALL: &[Kernel] = &[\n");
    for (k, _) in &kernels {
        let _ = writeln!(code, "        Kernel::{},", camel(k));
    }
    code.push_str("    ];\n\n    /// The entry point's name in the PTX.\n    pub const fn name(self) -> &'static str {\n        match self {\n");
    for (k, _) in &kernels {
        let _ = writeln!(code, "            Kernel::{} => {k:?},", camel(k));
    }
    code.push_str("        }\n    }\n}\n");
    let out =
        PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets it")).join("kernel_list.rs");
    std::fs::write(&out, code).expect("write the kernel list");
}
