//! Print the PTX of the kernel program (NVRTC, no GPU needed), for register and spill reports
//! with `ptxas -v` (scripts/kernel_report.sh).
//!
//! `cargo run -p rtmpm-cuda --example ptx -- [f64] [no_fast_math] [sm_90] [materials=0xMASK]
//! [layout=N] [ck_bound=N] [addressing=blocks] [uniform_loop=off] [row_unroll=N] [lean_lanes]
//! [seg_clamp] [zero_terms] [flat_checks] [state_index=wide] [lineinfo]` (N: the state layout's code, `StateLayout::code`:
//! 1 is the 20-word fluid layout; `ck_bound=N`: the CUDA option of the same name
//! (`CudaOptions::ck_min_blocks`); `lineinfo`: NVRTC's
//! `--generate-line-info`, so that `nvdisasm -g` names the source line of every SASS instruction;
//! not cached, the same code otherwise)

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
    // `ck_bound=5`: the kernels of that CUDA option.
    o.ck_min_blocks = args
        .iter()
        .find_map(|a| a.strip_prefix("ck_bound="))
        .and_then(|v| v.parse::<u32>().ok());
    // `addressing=blocks`: the stencil addressing of that CUDA option.
    o.stencil_pairs = !args.iter().any(|a| a == "addressing=blocks");
    // `uniform_loop=off`: the fused kernels' warp loop of that CUDA option.
    o.uniform_loop = !args.iter().any(|a| a == "uniform_loop=off");
    // `row_unroll=2`: RTMPM_P2G_UNROLL of the CUDA option `row_unroll` (2 planes, 1 all).
    o.row_unroll = args
        .iter()
        .find_map(|a| a.strip_prefix("row_unroll="))
        .and_then(|v| v.parse::<u32>().ok())
        .unwrap_or(0);
    // The instruction cuts of the CUDA options of the same names (`KernelCuts`), and
    // `state_index=wide` (the 64-bit state index).
    let has = |name: &str| args.iter().any(|a| a == name);
    o.cuts = rtmpm_cuda::KernelCuts {
        lean_lanes: has("lean_lanes"),
        seg_clamp: has("seg_clamp"),
        zero_terms: has("zero_terms"),
        flat_checks: has("flat_checks"),
    };
    o.state64 = has("state_index=wide");
    let ptx = if args.iter().any(|a| a == "lineinfo") {
        with_line_info(&o)
    } else {
        rtmpm_cuda::compile::compile(&o)
    };
    match ptx {
        Ok(ptx) => print!("{ptx}"),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}

/// The program's PTX with `.loc` line information (the backend's options plus
/// `--generate-line-info`, which changes no instruction).
fn with_line_info(o: &rtmpm_cuda::compile::KernelOptions) -> Result<String, String> {
    use rtmpm_cuda::compile;
    if !compile::nvrtc_available() {
        return Err("libnvrtc.so.13 not found (RTMPM_NVRTC_LIB)".into());
    }
    let mut options = compile::nvrtc_options(o);
    options.push("--generate-line-info".into());
    let src = compile::program_source(o.f64)?;
    let opts = cudarc::nvrtc::CompileOptions {
        options,
        name: Some("rtmpm_pipeline.cu".into()),
        ..Default::default()
    };
    match cudarc::nvrtc::compile_ptx_with_opts(src, opts) {
        Ok(p) => Ok(p.to_src()),
        Err(e) => Err(format!("NVRTC: {e:?}")),
    }
}
