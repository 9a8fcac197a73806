//! The CLI's closed choices as clap value enums (checked and listed by clap, `--help` shows
//! them), mapped onto the library's types.

use clap::ValueEnum;

/// `--mode`: the algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// rodtrack's algorithm.
    Enhanced,
    /// The published method, as a baseline.
    Paper,
}

impl From<ModeArg> for rodtrack_core::Mode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Enhanced => rodtrack_core::Mode::Enhanced,
            ModeArg::Paper => rodtrack_core::Mode::Paper,
        }
    }
}

/// `--format`: the rows' file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// Comma-separated values.
    Csv,
    /// JSON Lines.
    Jsonl,
}

impl From<FormatArg> for rodtrack_sdk::RowFormat {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Csv => rodtrack_sdk::RowFormat::Csv,
            FormatArg::Jsonl => rodtrack_sdk::RowFormat::Jsonl,
        }
    }
}

/// `--handoff`: who processes a camera's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HandoffArg {
    /// The thread that read the frame.
    Inline,
    /// A processing thread fed by a capture queue.
    Queue,
}

impl From<HandoffArg> for rodtrack_io::runtime::Handoff {
    fn from(h: HandoffArg) -> Self {
        match h {
            HandoffArg::Inline => rodtrack_io::runtime::Handoff::Inline,
            HandoffArg::Queue => rodtrack_io::runtime::Handoff::Queue,
        }
    }
}

/// `--write`: when rows are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WriteArg {
    /// Each camera's rows as soon as they are measured (the lowest latency; camera rows not
    /// flagged `conflict`).
    Camera,
    /// One write per frame set, after the fusion (camera rows the fusion overruled flagged
    /// `conflict`).
    Set,
}

impl From<WriteArg> for rodtrack_io::runtime::WriteMode {
    fn from(w: WriteArg) -> Self {
        match w {
            WriteArg::Camera => rodtrack_io::runtime::WriteMode::PerCamera,
            WriteArg::Set => rodtrack_io::runtime::WriteMode::Set,
        }
    }
}
