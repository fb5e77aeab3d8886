//! A grbl board to test against: the board simulator's grbl dialect
//! (three axes, X, Y and Z) on a new pseudo-terminal, its `$` settings
//! read from a file of its own.

use std::path::PathBuf;

use cogstep_protocol::Dialect;
use cogstep_sim::{BoardSim, GrblOptions, SimConfig};

/// Fast axes: 200 mm/s and 50,000 mm/s² at grbl's default 250 steps/mm.
pub const FAST: &str = "$110=12000\n$111=12000\n$112=12000\n$120=50000\n$121=50000\n$122=50000\n";

/// A running grbl board; stopped, and its settings file removed, when
/// dropped.
pub struct GrblBoard {
    sim: Option<BoardSim>,
    /// The device path to open.
    pub path: String,
    settings: PathBuf,
}

impl GrblBoard {
    /// Starts a board whose settings file (named after `name` and this
    /// process) holds `settings` (`$N=value` lines) when it starts.
    pub fn start(name: &str, settings: &str) -> GrblBoard {
        let file = std::env::temp_dir().join(format!(
            "cogstep-grbl-board-{}-{name}.settings",
            std::process::id()
        ));
        std::fs::write(&file, settings).expect("the settings file is written");
        let (sim, path) = BoardSim::spawn_pty_with(
            SimConfig {
                axes: 3,
                dialect: Dialect::Grbl,
                ..SimConfig::default()
            },
            GrblOptions {
                settings_file: Some(file.clone()),
            },
        )
        .expect("the grbl board starts");
        GrblBoard {
            sim: Some(sim),
            path,
            settings: file,
        }
    }
}

impl Drop for GrblBoard {
    fn drop(&mut self) {
        if let Some(sim) = self.sim.take() {
            sim.stop();
        }
        let _ = std::fs::remove_file(&self.settings);
    }
}
