//! `rtmpm info`.

use anyhow::Result;

pub fn info() -> Result<()> {
    println!("rtmpm {}", env!("CARGO_PKG_VERSION"));
    println!("backends:");
    println!("  cpu   available ({} threads)", rayon_threads());
    println!("  cuda  not built yet");
    Ok(())
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
