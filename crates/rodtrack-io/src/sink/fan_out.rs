//! Several sinks as one: rows, ball rows or events written to every sink of a [`FanOut`] (a file
//! and the UDP stream, the web console, ...).

use super::ball::BallSink;
use super::events::EventSink;
use super::MeasurementSink;
use crate::IoError;
use rodtrack_core::ball::events::BallEvent;
use rodtrack_core::ball::BallRow;
use rodtrack_core::Measurement;

/// Writes to several sinks of one kind (`S` is `dyn MeasurementSink`, `dyn BallSink` or `dyn
/// EventSink`): every sink gets every call even when an earlier one fails, and the first error
/// is returned after all were written.
pub struct FanOut<S: ?Sized> {
    /// The sinks.
    pub sinks: Vec<Box<S>>,
}

impl<S: ?Sized> Default for FanOut<S> {
    fn default() -> Self {
        FanOut { sinks: Vec::new() }
    }
}

impl<S: ?Sized> FanOut<S> {
    /// No sink yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a sink.
    pub fn push(&mut self, sink: Box<S>) {
        self.sinks.push(sink);
    }
}

/// Measurement rows to several sinks.
pub type MultiSink = FanOut<dyn MeasurementSink>;
/// Ball rows to several sinks.
pub type BallMultiSink = FanOut<dyn BallSink>;
/// Ball events to several sinks.
pub type EventMultiSink = FanOut<dyn EventSink>;

/// Runs every one of `results` (all of them, even after an error) and returns the first
/// error: what a sink writing to several others returns.
pub(crate) fn first_error(
    results: impl Iterator<Item = Result<(), IoError>>,
) -> Result<(), IoError> {
    let mut first = Ok(());
    for r in results {
        if first.is_ok() {
            first = r;
        }
    }
    first
}

macro_rules! fan_out {
    ($sink:ident, $item:ty) => {
        impl $sink for FanOut<dyn $sink> {
            fn write(&mut self, items: &[$item]) -> Result<(), IoError> {
                first_error(self.sinks.iter_mut().map(|s| s.write(items)))
            }
            fn flush(&mut self) -> Result<(), IoError> {
                first_error(self.sinks.iter_mut().map(|s| s.flush()))
            }
        }
    };
}

fan_out!(MeasurementSink, Measurement);

impl BallSink for FanOut<dyn BallSink> {
    fn write(&mut self, rows: &[BallRow]) -> Result<(), IoError> {
        first_error(self.sinks.iter_mut().map(|s| s.write(rows)))
    }
    fn write_sigma(&mut self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), IoError> {
        first_error(self.sinks.iter_mut().map(|s| s.write_sigma(rows, sigma_mm)))
    }
    fn flush(&mut self) -> Result<(), IoError> {
        first_error(self.sinks.iter_mut().map(|s| s.flush()))
    }
}

fan_out!(EventSink, BallEvent);
