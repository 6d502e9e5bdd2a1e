//! Print the PTX of the kernel program (NVRTC, no GPU needed), for register and spill reports
//! with `ptxas -v` (scripts/kernel_report.sh).
//!
//! `cargo run -p rtmpm-cuda --example ptx -- [f64] [no_fast_math] [sm_90]`

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arch = args
        .iter()
        .find_map(|a| a.strip_prefix("sm_"))
        .and_then(|a| a.parse::<i32>().ok())
        .map_or((9, 0), |v| (v / 10, v % 10));
    let o = rtmpm_cuda::compile::KernelOptions {
        arch,
        fast_math: !args.iter().any(|a| a == "no_fast_math"),
        f64: args.iter().any(|a| a == "f64"),
    };
    match rtmpm_cuda::compile::compile(&o) {
        Ok(ptx) => print!("{ptx}"),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
