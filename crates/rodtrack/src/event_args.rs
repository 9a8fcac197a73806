//! The ball's events on the command line: the file they go to and their rules, shared by
//! `track` (local cameras) and `fuse` (a camera network's fusion node).

use anyhow::{bail, Context, Result};
use rodtrack_core::ball::events::EventConfig;
use std::path::PathBuf;

/// `--events-out`, `--goal-width-mm`, `--events-config`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct EventArgs {
    /// Detect the ball's events (tracking the ball, with or without --ball-out) and write
    /// them to this JSON Lines file, one object per event: `goal`, `shot`, `ball_out`,
    /// `ball_stopped` (docs/formats.md). Needs the table frame in the calibration.
    #[arg(long)]
    pub events_out: Option<PathBuf>,
    /// The goal mouth's width, mm (the reference table's 205 by default).
    #[arg(long)]
    pub goal_width_mm: Option<f64>,
    /// The event rules' constants (TOML: any field of the events' configuration, e.g.
    /// `goal_grace_s = 0.8`, `field_length_mm = 1140`; docs/ball.md); --goal-width-mm wins.
    #[arg(long)]
    pub events_config: Option<PathBuf>,
}

impl EventArgs {
    /// The rules from `--events-config` and `--goal-width-mm` (the defaults otherwise).
    /// `detected`: whether the command detects the events at all (`what` names the options
    /// that ask for them, for the error when the rules are given without them).
    pub fn config(&self, detected: bool, what: &str) -> Result<EventConfig> {
        let mut cfg = match &self.events_config {
            Some(path) => {
                let text = std::fs::read_to_string(path).with_context(|| {
                    format!("reading the events configuration {}", path.display())
                })?;
                toml::from_str(&text)
                    .with_context(|| format!("the events configuration {}", path.display()))?
            }
            None => EventConfig::default(),
        };
        if let Some(w) = self.goal_width_mm {
            cfg.goal_width_mm = w;
        }
        if !detected && (self.events_config.is_some() || self.goal_width_mm.is_some()) {
            bail!("--events-config and --goal-width-mm set the events' rules: give {what}");
        }
        cfg.validate()
            .context("the events' rules (--events-config, --goal-width-mm)")?;
        Ok(cfg)
    }
}

/// The line a command prints for the events it wrote to `path`.
pub fn written(path: &std::path::Path, e: &rodtrack_sdk::EventCounts) -> String {
    format!("wrote {}: {e}", path.display())
}
