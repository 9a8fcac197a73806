//! [`McapWriter`]: an indexed MCAP file, its chunks uncompressed or LZ4 frames.
//!
//! Records are written little endian: opcode `u8`, content length `u64`, content. Strings
//! and byte arrays carry a `u32` length, maps a `u32` byte length. The writer keeps the open
//! chunk in memory and writes it, with its message indexes, when it reaches its
//! [`ChunkLimits`] or at [`McapWriter::flush`]; [`McapWriter::finish`] writes the summary and
//! the footer (dropping an unfinished writer finishes it, ignoring errors).

use super::{op, Crc32, MAGIC};
use crate::IoError;
use std::collections::BTreeMap;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

/// When the open chunk is written out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkLimits {
    /// Once its messages span this much log time, ns.
    pub span_ns: u64,
    /// Once its records hold this many bytes.
    pub bytes: usize,
}

impl Default for ChunkLimits {
    /// One second of log time or 1 MiB.
    fn default() -> Self {
        ChunkLimits {
            span_ns: 1_000_000_000,
            bytes: 1 << 20,
        }
    }
}

/// How chunks are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    /// Not compressed.
    #[default]
    None,
    /// LZ4 frames (the MCAP specification's `lz4`), pure Rust (`lz4_flex`).
    Lz4,
}

impl Compression {
    /// The name in chunk records: empty or `lz4`.
    pub fn name(self) -> &'static str {
        match self {
            Compression::None => "",
            Compression::Lz4 => "lz4",
        }
    }
}

/// What a finished file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WriteSummary {
    /// Messages written.
    pub messages: u64,
    /// Chunks written.
    pub chunks: u32,
    /// Schemas.
    pub schemas: u16,
    /// Channels.
    pub channels: u32,
    /// The earliest log time, ns (0 without messages).
    pub message_start_ns: u64,
    /// The latest log time, ns (0 without messages).
    pub message_end_ns: u64,
    /// The file's size, bytes.
    pub bytes: u64,
}

/// The output, with its position and the running CRC of the data section.
struct Out<W: Write> {
    w: BufWriter<W>,
    pos: u64,
    crc: Crc32,
}

impl<W: Write> Out<W> {
    fn write_all(&mut self, b: &[u8]) -> std::io::Result<()> {
        self.w.write_all(b)?;
        self.pos += b.len() as u64;
        self.crc.update(b);
        Ok(())
    }
}

/// Appends a record: opcode, content length, content.
fn push_record(buf: &mut Vec<u8>, opcode: u8, content: &[u8]) {
    buf.push(opcode);
    buf.extend_from_slice(&(content.len() as u64).to_le_bytes());
    buf.extend_from_slice(content);
}

fn push_str(buf: &mut Vec<u8>, s: &str) {
    push_bytes32(buf, s.as_bytes());
}

fn push_bytes32(buf: &mut Vec<u8>, b: &[u8]) {
    // Lengths are checked by the callers (names, schemas and messages well under 4 GiB).
    buf.extend_from_slice(&(b.len() as u32).to_le_bytes());
    buf.extend_from_slice(b);
}

/// Writes an MCAP file; see the module documentation.
pub struct McapWriter<W: Write> {
    out: Option<Out<W>>,
    name: PathBuf,
    limits: ChunkLimits,
    compression: Compression,
    /// The open chunk compressed (kept between chunks).
    packed: Vec<u8>,
    /// The schema and channel records, for the summary.
    schema_records: Vec<u8>,
    channel_records: Vec<u8>,
    schemas: u16,
    channels: u16,
    /// The open chunk's records, log time bounds and message index entries per channel.
    chunk: Vec<u8>,
    chunk_bounds: Option<(u64, u64)>,
    chunk_index: BTreeMap<u16, Vec<u8>>,
    /// The chunk index records, for the summary.
    chunk_index_records: Vec<u8>,
    chunks: u32,
    bounds: Option<(u64, u64)>,
    channel_counts: BTreeMap<u16, u64>,
    scratch: Vec<u8>,
    failed: bool,
}

impl<W: Write> McapWriter<W> {
    /// Starts a file on `w` (the magic and the header record: `profile`, empty or e.g.
    /// `ros2`, and `library`); `name` is used in error messages.
    pub fn new(
        w: W,
        name: impl Into<PathBuf>,
        profile: &str,
        library: &str,
        limits: ChunkLimits,
        compression: Compression,
    ) -> Result<Self, IoError> {
        let mut m = McapWriter {
            out: Some(Out {
                w: BufWriter::with_capacity(1 << 16, w),
                pos: 0,
                crc: Crc32::new(),
            }),
            name: name.into(),
            limits,
            compression,
            packed: Vec::new(),
            schema_records: Vec::new(),
            channel_records: Vec::new(),
            schemas: 0,
            channels: 0,
            chunk: Vec::with_capacity(limits.bytes.min(1 << 20) + 4096),
            chunk_bounds: None,
            chunk_index: BTreeMap::new(),
            chunk_index_records: Vec::new(),
            chunks: 0,
            bounds: None,
            channel_counts: BTreeMap::new(),
            scratch: Vec::with_capacity(256),
            failed: false,
        };
        let mut content = Vec::new();
        push_str(&mut content, profile);
        push_str(&mut content, library);
        let mut rec = MAGIC.to_vec();
        push_record(&mut rec, op::HEADER, &content);
        m.raw(&rec)?;
        m.flush_out()?;
        Ok(m)
    }

    fn error(&self, e: std::io::Error) -> IoError {
        IoError::file(&self.name, "cannot write", e)
    }

    /// Writes bytes to the file; a failure is remembered and later calls fail at once.
    fn raw(&mut self, b: &[u8]) -> Result<(), IoError> {
        if self.failed {
            return Err(self.error(std::io::Error::other("an earlier write failed")));
        }
        let Some(out) = self.out.as_mut() else {
            return Err(self.error(std::io::Error::other("the file is already finished")));
        };
        let r = out.write_all(b);
        r.map_err(|e| {
            self.failed = true;
            if let Some(out) = self.out.as_mut() {
                let _ = out.w.flush();
            }
            self.error(e)
        })
    }

    fn flush_out(&mut self) -> Result<(), IoError> {
        let r = match self.out.as_mut() {
            Some(out) => out.w.flush(),
            None => Ok(()),
        };
        r.map_err(|e| {
            self.failed = true;
            self.error(e)
        })
    }

    /// Adds a schema (`encoding`: e.g. `jsonschema`), written at once; returns its id (1, 2,
    /// ...).
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> Result<u16, IoError> {
        let id = self
            .schemas
            .checked_add(1)
            .ok_or_else(|| self.error(std::io::Error::other("too many schemas")))?;
        let mut c = Vec::with_capacity(data.len() + name.len() + 32);
        c.extend_from_slice(&id.to_le_bytes());
        push_str(&mut c, name);
        push_str(&mut c, encoding);
        push_bytes32(&mut c, data);
        let mut rec = Vec::with_capacity(c.len() + 9);
        push_record(&mut rec, op::SCHEMA, &c);
        self.raw(&rec)?;
        self.schemas = id;
        self.schema_records.extend_from_slice(&rec);
        Ok(id)
    }

    /// Adds a channel on `topic` with schema `schema_id` (0: none), messages in
    /// `message_encoding` (e.g. `json`), written at once; returns its id (1, 2, ...).
    pub fn add_channel(
        &mut self,
        schema_id: u16,
        topic: &str,
        message_encoding: &str,
        metadata: &[(&str, &str)],
    ) -> Result<u16, IoError> {
        let id = self
            .channels
            .checked_add(1)
            .ok_or_else(|| self.error(std::io::Error::other("too many channels")))?;
        let mut c = Vec::with_capacity(topic.len() + 64);
        c.extend_from_slice(&id.to_le_bytes());
        c.extend_from_slice(&schema_id.to_le_bytes());
        push_str(&mut c, topic);
        push_str(&mut c, message_encoding);
        let mut map = Vec::new();
        for (k, v) in metadata {
            push_str(&mut map, k);
            push_str(&mut map, v);
        }
        push_bytes32(&mut c, &map);
        let mut rec = Vec::with_capacity(c.len() + 9);
        push_record(&mut rec, op::CHANNEL, &c);
        self.raw(&rec)?;
        self.channels = id;
        self.channel_records.extend_from_slice(&rec);
        Ok(id)
    }

    /// Adds a message to the open chunk; the chunk is written when it reaches its limits.
    pub fn write_message(
        &mut self,
        channel: u16,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &[u8],
    ) -> Result<(), IoError> {
        if self.out.is_none() || self.failed {
            return self.raw(&[]);
        }
        if channel == 0 || channel > self.channels {
            return Err(self.error(std::io::Error::other(format!(
                "message on channel {channel}, which was not added"
            ))));
        }
        let offset = self.chunk.len() as u64;
        self.chunk.push(op::MESSAGE);
        self.chunk
            .extend_from_slice(&(22 + data.len() as u64).to_le_bytes());
        self.chunk.extend_from_slice(&channel.to_le_bytes());
        self.chunk.extend_from_slice(&sequence.to_le_bytes());
        self.chunk.extend_from_slice(&log_time_ns.to_le_bytes());
        self.chunk.extend_from_slice(&publish_time_ns.to_le_bytes());
        self.chunk.extend_from_slice(data);
        let entries = self.chunk_index.entry(channel).or_default();
        entries.extend_from_slice(&log_time_ns.to_le_bytes());
        entries.extend_from_slice(&offset.to_le_bytes());
        let widen = |b: Option<(u64, u64)>| match b {
            Some((lo, hi)) => (lo.min(log_time_ns), hi.max(log_time_ns)),
            None => (log_time_ns, log_time_ns),
        };
        self.chunk_bounds = Some(widen(self.chunk_bounds));
        self.bounds = Some(widen(self.bounds));
        *self.channel_counts.entry(channel).or_default() += 1;
        let (lo, hi) = self.chunk_bounds.unwrap_or_default();
        if self.chunk.len() >= self.limits.bytes || hi - lo >= self.limits.span_ns {
            self.close_chunk()?;
        }
        Ok(())
    }

    /// Writes the open chunk and its message indexes (nothing without messages), then pushes
    /// everything to the file.
    fn close_chunk(&mut self) -> Result<(), IoError> {
        let Some((start, end)) = self.chunk_bounds.take() else {
            return self.flush_out();
        };
        let chunk_start = self.out.as_ref().map_or(0, |o| o.pos);
        let size = self.chunk.len() as u64;
        let compression = self.compression;
        if compression == Compression::Lz4 {
            self.pack()?;
        }
        let stored = match compression {
            Compression::None => size,
            Compression::Lz4 => self.packed.len() as u64,
        };
        let mut rec = std::mem::take(&mut self.scratch);
        rec.clear();
        rec.push(op::CHUNK);
        let content_len = 8 + 8 + 8 + 4 + 4 + compression.name().len() as u64 + 8 + stored;
        rec.extend_from_slice(&content_len.to_le_bytes());
        rec.extend_from_slice(&start.to_le_bytes());
        rec.extend_from_slice(&end.to_le_bytes());
        rec.extend_from_slice(&size.to_le_bytes());
        rec.extend_from_slice(&Crc32::of(&self.chunk).to_le_bytes());
        push_str(&mut rec, compression.name());
        rec.extend_from_slice(&stored.to_le_bytes());
        let r = self.raw(&rec).and_then(|()| {
            let body = match compression {
                Compression::None => std::mem::take(&mut self.chunk),
                Compression::Lz4 => std::mem::take(&mut self.packed),
            };
            let r = self.raw(&body);
            match compression {
                Compression::None => self.chunk = body,
                Compression::Lz4 => self.packed = body,
            }
            r
        });
        self.scratch = rec;
        self.chunk.clear();
        let index = std::mem::take(&mut self.chunk_index);
        r?;
        let chunk_length = 9 + content_len;
        let index_start = chunk_start + chunk_length;
        let mut offsets = Vec::with_capacity(index.len() * 10);
        let mut records = Vec::new();
        for (channel, entries) in &index {
            offsets.extend_from_slice(&channel.to_le_bytes());
            offsets.extend_from_slice(&(index_start + records.len() as u64).to_le_bytes());
            let mut c = Vec::with_capacity(entries.len() + 6);
            c.extend_from_slice(&channel.to_le_bytes());
            push_bytes32(&mut c, entries);
            push_record(&mut records, op::MESSAGE_INDEX, &c);
        }
        self.raw(&records)?;
        let mut c = Vec::with_capacity(96 + offsets.len());
        for v in [start, end, chunk_start, chunk_length] {
            c.extend_from_slice(&v.to_le_bytes());
        }
        push_bytes32(&mut c, &offsets);
        c.extend_from_slice(&(records.len() as u64).to_le_bytes());
        push_str(&mut c, compression.name());
        c.extend_from_slice(&stored.to_le_bytes());
        c.extend_from_slice(&size.to_le_bytes());
        push_record(&mut self.chunk_index_records, op::CHUNK_INDEX, &c);
        self.chunks += 1;
        self.flush_out()
    }

    /// Compresses the open chunk into `packed` (an LZ4 frame).
    fn pack(&mut self) -> Result<(), IoError> {
        let mut packed = std::mem::take(&mut self.packed);
        packed.clear();
        let mut enc = lz4_flex::frame::FrameEncoder::new(packed);
        let r = enc
            .write_all(&self.chunk)
            .and_then(|()| enc.finish().map_err(std::io::Error::other));
        match r {
            Ok(p) => {
                self.packed = p;
                Ok(())
            }
            Err(e) => {
                self.failed = true;
                Err(self.error(e))
            }
        }
    }

    /// Writes the open chunk and pushes everything written to the file.
    pub fn flush(&mut self) -> Result<(), IoError> {
        self.close_chunk()
    }

    /// Writes the open chunk, the data end, the summary and the footer, and flushes. Returns
    /// what the file holds; later calls fail.
    pub fn finish(&mut self) -> Result<WriteSummary, IoError> {
        self.close_chunk()?;
        let data_crc = self.out.as_ref().map_or(0, |o| o.crc.value());
        let mut rec = Vec::new();
        push_record(&mut rec, op::DATA_END, &data_crc.to_le_bytes());
        self.raw(&rec)?;
        let summary_start = self.out.as_ref().map_or(0, |o| o.pos);
        let (lo, hi) = self.bounds.unwrap_or_default();
        let mut stats = Vec::new();
        stats.extend_from_slice(&self.channel_counts.values().sum::<u64>().to_le_bytes());
        stats.extend_from_slice(&self.schemas.to_le_bytes());
        stats.extend_from_slice(&u32::from(self.channels).to_le_bytes());
        stats.extend_from_slice(&0u32.to_le_bytes()); // attachments
        stats.extend_from_slice(&0u32.to_le_bytes()); // metadata
        stats.extend_from_slice(&self.chunks.to_le_bytes());
        stats.extend_from_slice(&lo.to_le_bytes());
        stats.extend_from_slice(&hi.to_le_bytes());
        let mut counts = Vec::new();
        for (channel, n) in &self.channel_counts {
            counts.extend_from_slice(&channel.to_le_bytes());
            counts.extend_from_slice(&n.to_le_bytes());
        }
        push_bytes32(&mut stats, &counts);
        let mut stats_record = Vec::new();
        push_record(&mut stats_record, op::STATISTICS, &stats);
        let mut summary = Vec::new();
        let mut offsets = Vec::new();
        for (opcode, group) in [
            (op::SCHEMA, &self.schema_records),
            (op::CHANNEL, &self.channel_records),
            (op::STATISTICS, &stats_record),
            (op::CHUNK_INDEX, &self.chunk_index_records),
        ] {
            if group.is_empty() {
                continue;
            }
            let mut c = vec![opcode];
            c.extend_from_slice(&(summary_start + summary.len() as u64).to_le_bytes());
            c.extend_from_slice(&(group.len() as u64).to_le_bytes());
            push_record(&mut offsets, op::SUMMARY_OFFSET, &c);
            summary.extend_from_slice(group);
        }
        let summary_offset_start = summary_start + summary.len() as u64;
        summary.extend_from_slice(&offsets);
        summary.push(op::FOOTER);
        summary.extend_from_slice(&20u64.to_le_bytes());
        summary.extend_from_slice(&summary_start.to_le_bytes());
        summary.extend_from_slice(&summary_offset_start.to_le_bytes());
        let crc = Crc32::of(&summary);
        summary.extend_from_slice(&crc.to_le_bytes());
        summary.extend_from_slice(&MAGIC);
        self.raw(&summary)?;
        self.flush_out()?;
        let bytes = self.out.as_ref().map_or(0, |o| o.pos);
        self.out = None;
        Ok(WriteSummary {
            messages: self.channel_counts.values().sum(),
            chunks: self.chunks,
            schemas: self.schemas,
            channels: u32::from(self.channels),
            message_start_ns: lo,
            message_end_ns: hi,
            bytes,
        })
    }

    /// Whether [`McapWriter::finish`] has run (or the file is closed after a failure).
    pub fn is_finished(&self) -> bool {
        self.out.is_none()
    }
}

impl<W: Write> Drop for McapWriter<W> {
    fn drop(&mut self) {
        if self.out.is_some() && !self.failed {
            let _ = self.finish();
        }
    }
}
