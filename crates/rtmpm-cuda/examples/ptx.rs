//! Print the PTX of the kernel program (NVRTC, no GPU needed), for register and spill reports
//! with `ptxas -v` (scripts/kernel_report.sh).
//!
//! `cargo run -p rtmpm-cuda --example ptx -- [f64] [no_fast_math] [sm_90] [materials=0xMASK]
//! [layout=N]` (N: the state layout's code, `StateLayout::code`: 1 is the 20-word fluid layout)

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arch = args
        .iter()
        .find_map(|a| a.strip_prefix("sm_"))
        .and_then(|a| a.parse::<i32>().ok())
        .map_or((9, 0), |v| (v / 10, v % 10));
    // `materials=0x11`: the program of a scene with those model kinds (default: every model).
    let mut o = rtmpm_cuda::compile::KernelOptions::all_models(
        arch,
        !args.iter().any(|a| a == "no_fast_math"),
        args.iter().any(|a| a == "f64"),
    );
    if let Some(m) = args.iter().find_map(|a| a.strip_prefix("materials=0x")) {
        o.materials = u32::from_str_radix(m, 16).unwrap_or(u32::MAX);
    }
    // `layout=1`: the program of a scene in that state layout (`StateLayout::code`).
    if let Some(l) = args
        .iter()
        .find_map(|a| a.strip_prefix("layout="))
        .and_then(|code| {
            rtmpm_cuda::contract::StateLayout::ALL
                .into_iter()
                .find(|l| code.parse() == Ok(l.code()))
        })
    {
        o.layout = l;
    }
    match rtmpm_cuda::compile::compile(&o) {
        Ok(ptx) => print!("{ptx}"),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
