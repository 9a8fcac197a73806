//! [`read_mcap`]: the schemas, channels and messages of an MCAP file, in file order.
//!
//! Reads the data section record by record: `Schema`, `Channel` and `Message` records, and
//! the same inside `Chunk`s, uncompressed or LZ4 frames (at most [`MAX_CHUNK_BYTES`]
//! uncompressed; the CRC is checked when it is given). Other records are skipped. A chunk
//! compressed otherwise (zstd) is refused with its compression named. A file cut
//! short (a crash while recording) gives what precedes the cut, with
//! [`McapFile::complete`] false and the reason in [`McapFile::cut`].

use super::{op, Crc32, MAGIC};
use crate::IoError;
use std::collections::BTreeMap;
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// The largest uncompressed chunk read, bytes (writers' chunks are a few MiB; a larger
/// claim is refused before anything is allocated for it).
pub const MAX_CHUNK_BYTES: u64 = 256 << 20;

/// A schema record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapSchema {
    /// Its id.
    pub id: u16,
    /// Its name.
    pub name: String,
    /// Its encoding (`jsonschema`, ...).
    pub encoding: String,
    /// The schema itself.
    pub data: Vec<u8>,
}

/// A channel record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapChannel {
    /// Its id.
    pub id: u16,
    /// Its schema's id (0: none).
    pub schema_id: u16,
    /// The topic.
    pub topic: String,
    /// The messages' encoding (`json`, ...).
    pub message_encoding: String,
    /// Its metadata.
    pub metadata: BTreeMap<String, String>,
}

/// A message record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapMessage {
    /// The channel's id.
    pub channel: u16,
    /// Sequence number.
    pub sequence: u32,
    /// Log time, ns.
    pub log_time_ns: u64,
    /// Publish time, ns.
    pub publish_time_ns: u64,
    /// The message.
    pub data: Vec<u8>,
}

/// What [`read_mcap`] found.
#[derive(Debug, Clone, Default)]
pub struct McapFile {
    /// The header's profile field (`ros2`, or empty).
    pub profile: String,
    /// The header's library field.
    pub library: String,
    /// Schemas by id.
    pub schemas: BTreeMap<u16, McapSchema>,
    /// Channels by id.
    pub channels: BTreeMap<u16, McapChannel>,
    /// Messages in file order.
    pub messages: Vec<McapMessage>,
    /// Whether the data section ended with its `DataEnd` record.
    pub complete: bool,
    /// Where and why the file stopped early, when it did.
    pub cut: Option<String>,
}

impl McapFile {
    /// The channel of `topic`.
    pub fn channel(&self, topic: &str) -> Option<&McapChannel> {
        self.channels.values().find(|c| c.topic == topic)
    }
}

/// A cursor over one record's fields.
struct Fields<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Fields<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.at.checked_add(n)?;
        let s = self.b.get(self.at..end)?;
        self.at = end;
        Some(s)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take(2)?.try_into().ok().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take(4)?.try_into().ok().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Option<u64> {
        self.take(8)?.try_into().ok().map(u64::from_le_bytes)
    }
    fn bytes32(&mut self) -> Option<&'a [u8]> {
        let n = self.u32()? as usize;
        self.take(n)
    }
    fn string(&mut self) -> Option<String> {
        String::from_utf8(self.bytes32()?.to_vec()).ok()
    }
    fn rest(&mut self) -> &'a [u8] {
        let s = self.b.get(self.at..).unwrap_or_default();
        self.at = self.b.len();
        s
    }
}

/// Reads an MCAP file; see the module documentation.
pub fn read_mcap(path: &Path) -> Result<McapFile, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::file(path, "cannot read", e))?;
    parse_mcap(&bytes, path)
}

/// Parses the bytes of an MCAP file; `name` is used in error messages.
pub fn parse_mcap(bytes: &[u8], name: &Path) -> Result<McapFile, IoError> {
    let bad = |reason: String| IoError::Recording {
        path: PathBuf::from(name),
        reason,
    };
    if bytes.get(..MAGIC.len()) != Some(&MAGIC[..]) {
        return Err(bad("not an MCAP file (no MCAP magic at its start)".into()));
    }
    let mut file = McapFile::default();
    let mut reader = Reader {
        file: &mut file,
        bad: &bad,
    };
    let end = reader.records(bytes, MAGIC.len(), false)?;
    if let Some(at) = end {
        file.cut = Some(format!(
            "cut short at byte {at} of {}: the recording did not finish (the messages before are read)",
            bytes.len()
        ));
    }
    Ok(file)
}

struct Reader<'f, 'b> {
    file: &'f mut McapFile,
    bad: &'b dyn Fn(String) -> IoError,
}

impl Reader<'_, '_> {
    /// Reads the records of `b` from `at`; returns the offset of a record cut short, if any.
    fn records(
        &mut self,
        b: &[u8],
        mut at: usize,
        in_chunk: bool,
    ) -> Result<Option<usize>, IoError> {
        while at < b.len() {
            let (Some(&opcode), Some(len)) = (
                b.get(at),
                b.get(at + 1..at + 9)
                    .and_then(|s| s.try_into().ok())
                    .map(u64::from_le_bytes),
            ) else {
                return Ok(Some(at));
            };
            let start = at + 9;
            let Some(content) = usize::try_from(len)
                .ok()
                .and_then(|len| start.checked_add(len))
                .and_then(|end| b.get(start..end))
            else {
                if in_chunk {
                    return Err((self.bad)(format!(
                        "a record in a chunk runs past the chunk's end ({len} bytes at {at})"
                    )));
                }
                return Ok(Some(at));
            };
            at = start + content.len();
            if self.record(opcode, content, at - content.len() - 9)? && !in_chunk {
                self.file.complete = true;
                return Ok(None);
            }
        }
        if in_chunk {
            Ok(None)
        } else {
            // The data section stopped without DataEnd.
            Ok(Some(b.len()))
        }
    }

    /// Reads one record; true at `DataEnd`.
    fn record(&mut self, opcode: u8, content: &[u8], at: usize) -> Result<bool, IoError> {
        let mut f = Fields { b: content, at: 0 };
        let short = || {
            (self.bad)(format!(
                "record 0x{opcode:02x} at byte {at} is too short or not UTF-8"
            ))
        };
        match opcode {
            op::HEADER => {
                self.file.profile = f.string().ok_or_else(short)?;
                self.file.library = f.string().ok_or_else(short)?;
            }
            op::SCHEMA => {
                let s = McapSchema {
                    id: f.u16().ok_or_else(short)?,
                    name: f.string().ok_or_else(short)?,
                    encoding: f.string().ok_or_else(short)?,
                    data: f.bytes32().ok_or_else(short)?.to_vec(),
                };
                self.file.schemas.insert(s.id, s);
            }
            op::CHANNEL => {
                let id = f.u16().ok_or_else(short)?;
                let schema_id = f.u16().ok_or_else(short)?;
                let topic = f.string().ok_or_else(short)?;
                let message_encoding = f.string().ok_or_else(short)?;
                let mut map = Fields {
                    b: f.bytes32().ok_or_else(short)?,
                    at: 0,
                };
                let mut metadata = BTreeMap::new();
                while map.at < map.b.len() {
                    let k = map.string().ok_or_else(short)?;
                    let v = map.string().ok_or_else(short)?;
                    metadata.insert(k, v);
                }
                self.file.channels.insert(
                    id,
                    McapChannel {
                        id,
                        schema_id,
                        topic,
                        message_encoding,
                        metadata,
                    },
                );
            }
            op::MESSAGE => {
                let m = McapMessage {
                    channel: f.u16().ok_or_else(short)?,
                    sequence: f.u32().ok_or_else(short)?,
                    log_time_ns: f.u64().ok_or_else(short)?,
                    publish_time_ns: f.u64().ok_or_else(short)?,
                    data: f.rest().to_vec(),
                };
                if !self.file.channels.contains_key(&m.channel) {
                    return Err((self.bad)(format!(
                        "a message at byte {at} on channel {}, which no channel record defines",
                        m.channel
                    )));
                }
                self.file.messages.push(m);
            }
            op::CHUNK => {
                let _start = f.u64().ok_or_else(short)?;
                let _end = f.u64().ok_or_else(short)?;
                let size = f.u64().ok_or_else(short)?;
                let crc = f.u32().ok_or_else(short)?;
                let compression = f.string().ok_or_else(short)?;
                let n = f.u64().ok_or_else(short)?;
                let records = usize::try_from(n)
                    .ok()
                    .and_then(|n| f.take(n))
                    .ok_or_else(short)?;
                let unpacked;
                let records = match compression.as_str() {
                    "" => records,
                    "lz4" => {
                        unpacked = self.lz4(records, size, at)?;
                        &unpacked[..]
                    }
                    other => {
                        return Err((self.bad)(format!(
                            "the chunk at byte {at} is compressed with {other:?}; this reader reads uncompressed and lz4 chunks (rodtrack writes those)"
                        )));
                    }
                };
                if records.len() as u64 != size || (crc != 0 && Crc32::of(records) != crc) {
                    return Err((self.bad)(format!(
                        "the chunk at byte {at} is damaged (its size or CRC does not match)"
                    )));
                }
                self.records(records, 0, true)?;
            }
            op::DATA_END => return Ok(true),
            _ => {}
        }
        Ok(false)
    }

    /// An LZ4 frame's content, `size` bytes (at most [`MAX_CHUNK_BYTES`]; memory grows with
    /// what the frame really holds, not with `size`).
    fn lz4(&self, packed: &[u8], size: u64, at: usize) -> Result<Vec<u8>, IoError> {
        if size > MAX_CHUNK_BYTES {
            return Err((self.bad)(format!(
                "the chunk at byte {at} claims {size} bytes uncompressed, more than the {MAX_CHUNK_BYTES} read"
            )));
        }
        let mut out = Vec::with_capacity(packed.len().saturating_mul(4).min(size as usize));
        lz4_flex::frame::FrameDecoder::new(packed)
            .take(size + 1)
            .read_to_end(&mut out)
            .map_err(|e| {
                (self.bad)(format!(
                    "the chunk at byte {at} is damaged (its LZ4 frame: {e})"
                ))
            })?;
        Ok(out)
    }
}
