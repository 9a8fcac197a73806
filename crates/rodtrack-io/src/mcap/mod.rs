//! MCAP recordings (<https://mcap.dev>), the container that Foxglove and Rerun open: a small
//! writer and reader of the format itself (LZ4 through `lz4_flex`), and [`McapRecorder`],
//! which records measurement rows, joint states and optional grey frames as JSON messages, or
//! joint states as ROS 2 `sensor_msgs/msg/JointState` in CDR in a ROS 2 bag.
//!
//! - [`mod@write`]: [`McapWriter`], records little endian (opcode `u8`, length `u64`, fields):
//!   the magic, `Header`, then `Schema` and `Channel` records as they are first used, the
//!   messages in `Chunk`s (uncompressed or LZ4 frames, [`Compression`]) each followed by its
//!   `MessageIndex` records, `DataEnd`
//!   (with the data section's CRC-32), a summary section (schemas, channels, `Statistics`,
//!   `ChunkIndex` records, `SummaryOffset`s), the `Footer` and the magic again. Files are
//!   indexed, so that viewers seek instead of reading the whole file.
//! - [`mod@read`]: [`read_mcap`], the schemas, channels and messages of a file in file order,
//!   from chunks (uncompressed or LZ4) or outside chunks; a file cut short (a crash) gives the
//!   complete chunks before the cut.
//! - [`record`]: [`McapRecorder`], the channels and schemas of rodtrack's recordings.
//! - [`mod@ball`]: the ball's rows in recordings ([`McapRecorder::ball_sink`]).
//! - [`mod@events`]: the ball's events in recordings ([`McapRecorder::event_sink`]).
//! - [`ros2`]: [`JointState`] in CDR, its `ros2msg` schema and QoS metadata.
//!
//! What a crash leaves: every chunk closed before it (a chunk is closed after at most
//! [`ChunkLimits::span_ns`] of log time or [`ChunkLimits::bytes`], and at every flush), with no
//! summary: readers that stream the file (this module's, the `mcap` tools' `recover`) read
//! those chunks; the open chunk's messages are lost.

pub mod ball;
pub mod events;
pub mod read;
pub mod record;
pub mod ros2;
pub mod write;

pub use ball::{parse_ball_message, BallMessage, McapBallSink, BALL_SCHEMA, BALL_SCHEMA_NAME};
pub use events::{parse_event_message, McapEventSink, EVENT_SCHEMA, EVENT_SCHEMA_NAME};
pub use read::{
    parse_mcap, read_mcap, McapChannel, McapFile, McapMessage, McapSchema, MAX_CHUNK_BYTES,
};
pub use record::{
    parse_rows_message, McapRecorder, McapSink, Profile, RecordOptions, RowsMessage, IMAGE_SCHEMA,
    IMAGE_SCHEMA_NAME, JOINTS_SCHEMA, JOINTS_SCHEMA_NAME, ROWS_SCHEMA, ROWS_SCHEMA_NAME,
};
pub use ros2::{
    ball_place_and_velocity, JointState, StampedXyz, JOINT_STATE_MSGDEF, JOINT_STATE_SCHEMA_NAME,
    POINT_STAMPED_MSGDEF, POINT_STAMPED_SCHEMA_NAME, VECTOR3_STAMPED_MSGDEF,
    VECTOR3_STAMPED_SCHEMA_NAME,
};
pub use write::{ChunkLimits, Compression, McapWriter, WriteSummary};

/// The 8 bytes at the start and the end of an MCAP file.
pub const MAGIC: [u8; 8] = [0x89, b'M', b'C', b'A', b'P', b'0', b'\r', b'\n'];

/// Record opcodes (MCAP specification, version 0).
pub mod op {
    /// Header.
    pub const HEADER: u8 = 0x01;
    /// Footer.
    pub const FOOTER: u8 = 0x02;
    /// Schema.
    pub const SCHEMA: u8 = 0x03;
    /// Channel.
    pub const CHANNEL: u8 = 0x04;
    /// Message.
    pub const MESSAGE: u8 = 0x05;
    /// Chunk.
    pub const CHUNK: u8 = 0x06;
    /// Message index.
    pub const MESSAGE_INDEX: u8 = 0x07;
    /// Chunk index.
    pub const CHUNK_INDEX: u8 = 0x08;
    /// Statistics.
    pub const STATISTICS: u8 = 0x0B;
    /// Summary offset.
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    /// Data end.
    pub const DATA_END: u8 = 0x0F;
}

/// CRC-32 (IEEE 802.3, the one of zlib and MCAP), kept running over bytes as they pass.
#[derive(Debug, Clone, Copy)]
pub struct Crc32(u32);

const CRC_TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

impl Default for Crc32 {
    fn default() -> Self {
        Crc32::new()
    }
}

impl Crc32 {
    /// The CRC of no bytes.
    pub fn new() -> Self {
        Crc32(0xFFFF_FFFF)
    }
    /// Adds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        let mut c = self.0;
        for &b in bytes {
            c = CRC_TABLE[((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
        }
        self.0 = c;
    }
    /// The CRC of the bytes so far.
    pub fn value(&self) -> u32 {
        !self.0
    }
    /// The CRC of `bytes`.
    pub fn of(bytes: &[u8]) -> u32 {
        let mut c = Crc32::new();
        c.update(bytes);
        c.value()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_zlibs() {
        assert_eq!(Crc32::of(b""), 0);
        assert_eq!(Crc32::of(b"123456789"), 0xCBF4_3926);
        let mut c = Crc32::new();
        c.update(b"1234");
        c.update(b"56789");
        assert_eq!(c.value(), 0xCBF4_3926);
    }
}
