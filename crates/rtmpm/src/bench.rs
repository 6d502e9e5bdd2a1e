//! `rtmpm bench`: the classic MLS-MPM fluid block.

use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct BenchArgs {
    /// Grid resolution n (dx = 1/n, n^3/4 particles).
    #[arg(long, default_value_t = 64)]
    pub n: u32,
}

pub fn bench(_args: BenchArgs) -> Result<()> {
    anyhow::bail!("not yet")
}
