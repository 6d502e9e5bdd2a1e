//! Command-line options of multi-GPU runs: several GPUs of one process (`--gpus`), or one process
//! per GPU meeting through a rendezvous (`--rendezvous`, any launcher, several machines).

use anyhow::{Result, bail};
use clap::Args;
use rtmpm_cuda::CudaOptions;
use rtmpm_cuda::rendezvous::Rendezvous;
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

/// Multi-GPU options of `rtmpm run`.
#[derive(Args, Clone, Debug, Default)]
pub struct MultiGpuArgs {
    /// Run on several GPUs of this machine: a number, or `all` (CUDA backend; peer-to-peer between the GPUs, or NCCL: --cuda-options transport=p2p|nccl).
    #[arg(long, value_name = "N|all")]
    pub gpus: Option<String>,
    /// One process per GPU: where the processes meet, `tcp://HOST:PORT` (rank 0's host; rank 0
    /// listens on PORT) or `file:PATH` (a new file on a filesystem every process sees).
    #[arg(long, value_name = "URL")]
    pub rendezvous: Option<Rendezvous>,
    /// This process's rank, 0..ranks (default: from RANK, OMPI_COMM_WORLD_RANK, PMI_RANK or
    /// SLURM_PROCID).
    #[arg(long, value_name = "R")]
    pub nccl_rank: Option<usize>,
    /// Number of processes (default: from WORLD_SIZE, OMPI_COMM_WORLD_SIZE, PMI_SIZE or
    /// SLURM_NTASKS).
    #[arg(long, value_name = "N")]
    pub nccl_ranks: Option<usize>,
    /// CUDA device of this process (default: the local rank from LOCAL_RANK,
    /// OMPI_COMM_WORLD_LOCAL_RANK, MPI_LOCALRANKID or SLURM_LOCALID, else rank % devices).
    #[arg(long, value_name = "D")]
    pub device: Option<usize>,
}

fn env_usize(names: &[&str]) -> Option<usize> {
    names
        .iter()
        .find_map(|n| std::env::var(n).ok().and_then(|v| v.trim().parse().ok()))
}

/// What this process is in the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One GPU or the CPU.
    Single,
    /// Several GPUs of this process.
    Gpus(usize),
    /// Rank `rank` of `ranks` processes.
    Rank { rank: usize, ranks: usize },
}

impl MultiGpuArgs {
    /// The mode these options ask for.
    pub fn mode(&self) -> Result<Mode> {
        if let Some(r) = &self.rendezvous {
            if self.gpus.is_some() {
                bail!(
                    "--gpus and --rendezvous exclude each other: a multi-process run has one GPU per process"
                );
            }
            let rank = self.nccl_rank.or_else(|| {
                env_usize(&["RANK", "OMPI_COMM_WORLD_RANK", "PMI_RANK", "SLURM_PROCID"])
            });
            let ranks = self.nccl_ranks.or_else(|| {
                env_usize(&[
                    "WORLD_SIZE",
                    "OMPI_COMM_WORLD_SIZE",
                    "PMI_SIZE",
                    "SLURM_NTASKS",
                ])
            });
            let (Some(rank), Some(ranks)) = (rank, ranks) else {
                bail!(
                    "--rendezvous {r:?}: give --nccl-rank R and --nccl-ranks N (or start the \
                     processes with mpirun or srun, which set them)"
                );
            };
            if ranks == 0 || rank >= ranks {
                bail!("--nccl-rank {rank} must be in 0..{ranks} (--nccl-ranks {ranks})");
            }
            return Ok(Mode::Rank { rank, ranks });
        }
        if self.nccl_rank.is_some() || self.nccl_ranks.is_some() || self.device.is_some() {
            bail!(
                "--nccl-rank, --nccl-ranks and --device need --rendezvous tcp://HOST:PORT or file:PATH"
            );
        }
        match self.gpus.as_deref() {
            None => Ok(Mode::Single),
            Some("all") => match rtmpm_cuda::device_count() {
                0 => bail!(
                    "--gpus all: no CUDA device is usable here ({})",
                    rtmpm_cuda::probe()
                        .err()
                        .map(|e| e.to_string())
                        .unwrap_or_default()
                ),
                1 => Ok(Mode::Single),
                n => Ok(Mode::Gpus(n)),
            },
            Some(s) => match s.parse::<usize>() {
                Ok(0) | Err(_) => {
                    bail!("--gpus {s}: expected a number of GPUs (1, 2, ...) or `all`")
                }
                Ok(1) => Ok(Mode::Single),
                Ok(n) => Ok(Mode::Gpus(n)),
            },
        }
    }

    /// True when this process writes the run's files (rank 0, or not a multi-process run).
    pub fn writes_output(&self) -> bool {
        !matches!(self.mode(), Ok(Mode::Rank { rank, .. }) if rank != 0)
    }

    /// The multi-GPU backend of `mode` (not [`Mode::Single`]).
    pub fn backend(
        &self,
        mode: Mode,
        scene: &Scene,
        particles: &Particles,
        options: &CudaOptions,
    ) -> Result<Box<dyn Backend>> {
        match mode {
            Mode::Single => bail!("not a multi-GPU run"),
            Mode::Gpus(n) => Ok(Box::new(rtmpm_cuda::MultiGpuBackend::new(
                scene,
                particles,
                n,
                options.clone(),
            )?)),
            Mode::Rank { rank, ranks } => {
                let Some(r) = &self.rendezvous else {
                    bail!("multi-process runs need --rendezvous");
                };
                let devices = rtmpm_cuda::device_count();
                if devices == 0 {
                    bail!(
                        "rank {rank}: no CUDA device is usable here ({})",
                        rtmpm_cuda::probe()
                            .err()
                            .map(|e| e.to_string())
                            .unwrap_or_default()
                    );
                }
                let device = self
                    .device
                    .or_else(|| {
                        env_usize(&[
                            "LOCAL_RANK",
                            "OMPI_COMM_WORLD_LOCAL_RANK",
                            "MPI_LOCALRANKID",
                            "SLURM_LOCALID",
                        ])
                    })
                    .unwrap_or(rank % devices);
                if device >= devices {
                    bail!("rank {rank}: --device {device}, but {devices} CUDA device(s) found");
                }
                Ok(Box::new(rtmpm_cuda::NcclRankBackend::new(
                    scene,
                    particles,
                    rank,
                    ranks,
                    device,
                    r,
                    options.clone(),
                )?))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(
        gpus: Option<&str>,
        rdv: Option<&str>,
        rank: Option<usize>,
        ranks: Option<usize>,
    ) -> MultiGpuArgs {
        MultiGpuArgs {
            gpus: gpus.map(String::from),
            rendezvous: rdv.map(|r| r.parse().unwrap()),
            nccl_rank: rank,
            nccl_ranks: ranks,
            device: None,
        }
    }

    #[test]
    fn modes_from_the_options() {
        assert_eq!(args(None, None, None, None).mode().unwrap(), Mode::Single);
        assert_eq!(
            args(Some("1"), None, None, None).mode().unwrap(),
            Mode::Single
        );
        assert_eq!(
            args(Some("4"), None, None, None).mode().unwrap(),
            Mode::Gpus(4)
        );
        assert!(args(Some("0"), None, None, None).mode().is_err());
        assert!(args(Some("two"), None, None, None).mode().is_err());
        let m = args(None, Some("tcp://h:1234"), Some(1), Some(2))
            .mode()
            .unwrap();
        assert_eq!(m, Mode::Rank { rank: 1, ranks: 2 });
        assert!(!args(None, Some("tcp://h:1234"), Some(1), Some(2)).writes_output());
        assert!(args(None, Some("tcp://h:1234"), Some(0), Some(2)).writes_output());
        assert!(
            args(None, Some("tcp://h:1234"), Some(2), Some(2))
                .mode()
                .is_err()
        );
        assert!(
            args(Some("2"), Some("tcp://h:1234"), Some(0), Some(2))
                .mode()
                .is_err()
        );
        assert!(args(None, None, Some(0), Some(2)).mode().is_err());
    }
}
