//! rodtrack's I/O: frame sources (image sequences, raw files, and a trait for cameras and the
//! simulator), measurement sinks (CSV, JSON Lines, UDP), the measurement file reader, and the
//! multi-camera runtime pipeline.
//!
//! Layout:
//! - [`frame`]: [`FrameMeta`], [`FrameBuffer`] (owned bytes + metadata, lends a
//!   [`rodtrack_core::FrameView`]), [`BufferPool`], [`Timestamp`];
//! - [`source`]: the [`FrameSource`] trait, [`ImageSequence`], [`RawSource`], input strings and
//!   the [`SourceFactory`];
//! - [`sink`]: the [`MeasurementSink`] trait, [`CsvSink`], [`JsonlSink`], [`UdpSink`], readers;
//! - [`mcap`]: MCAP recordings (rows, joint states, frames) for Foxglove and Rerun, and their
//!   reader;
//! - [`runtime`]: capture threads, bounded queues, per-camera processing, frame-set grouping,
//!   latency statistics.

// The runtime's unit tests share their fakes with the integration tests, which name this crate.
#[cfg(test)]
extern crate self as rodtrack_io;

pub mod error;
pub mod frame;
pub mod mcap;
pub mod runtime;
pub mod sink;
pub mod source;

pub use error::{IoError, SourceError};
pub use frame::{BufferPool, FrameBuffer, FrameMeta, Timestamp};
pub use sink::{
    decode_udp_ball, decode_udp_events, decode_udp_packet, parse_event_json, read_events_jsonl,
    read_measurements_csv, read_measurements_jsonl, BallCsvSink, BallJsonlSink, BallMultiSink,
    BallSink, BallVecSink, CsvSink, EventJsonlSink, EventMultiSink, EventSink, EventVecSink,
    JsonlSink, MeasurementSink, MultiSink, UdpBallSink, UdpEventSink, UdpSink, VecSink,
};
pub use source::{
    FrameSource, ImageSequence, ImageSequenceOptions, InputSpec, OpenOptions, RawOptions,
    RawSource, SourceFactory, SourceInfo,
};
