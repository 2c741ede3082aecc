//! Measurement tools, as library code: what `gloam bench` (`frames`), `raybench`,
//! `flythrough`, `convergence` and `exposure` (`exposure_map`) measure. Each module's `Options` is its command's flags
//! (the command line parses them and calls `run`); each `run` prints its table and writes
//! its reports. Outside the frame: these drive the engine's own steps and time them.

pub mod convergence;
pub mod exposure_map;
pub mod flythrough;
pub mod frames;
pub mod progress;
pub mod raybench;

/// `--filter`: which of the film's real-time filters run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FilterArg {
    /// The raw frame (still views accumulate).
    Raw,
    /// Temporal reprojection only.
    Temporal,
    /// Temporal reprojection, then the a-trous spatial filter.
    Full,
}

impl FilterArg {
    pub fn mode(self) -> crate::film::denoise::FilterMode {
        use crate::film::denoise::FilterMode;
        match self {
            FilterArg::Raw => FilterMode::Off,
            FilterArg::Temporal => FilterMode::Temporal,
            FilterArg::Full => FilterMode::Full,
        }
    }
}

/// Worker threads when a command is not told: every core.
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
