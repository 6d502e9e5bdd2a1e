//! `rtmpm info`.

use anyhow::Result;

pub fn info() -> Result<()> {
    println!("rtmpm {}", env!("CARGO_PKG_VERSION"));
    println!("backends:");
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("  cpu   available ({threads} threads)");
    match rtmpm_cuda::probe() {
        Ok(d) => {
            println!("  cuda  available");
            println!(
                "        device {} (compute {}.{}, {} SMs, {:.1} GiB), driver {}.{}",
                d.name,
                d.compute_capability.0,
                d.compute_capability.1,
                d.sm_count,
                d.memory as f64 / (1u64 << 30) as f64,
                d.driver_version / 1000,
                (d.driver_version % 1000) / 10
            );
            if let Some(dir) = rtmpm_cuda::compile::cache_dir() {
                println!("        kernel cache {}", dir.display());
            }
        }
        Err(why) => println!("  cuda  not usable: {why}"),
    }
    println!(
        "default (--backend auto): {}",
        if rtmpm_cuda::probe().is_ok() {
            "cuda"
        } else {
            "cpu"
        }
    );
    Ok(())
}
