//! The zenoh session of a node, its key expressions and its publishers.

use crate::layout::{self, Header, Kind};
use crate::{ball_layout, ZenohError};
use rodtrack_core::ball::events::BallEvent;
use rodtrack_core::ball::BallRow;
use rodtrack_core::Measurement;
use rodtrack_io::IoError;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Mutex;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

/// The default table name in key expressions.
pub const DEFAULT_TABLE: &str = "default";

/// How rows are encoded on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WireFormat {
    /// The binary layout ([`layout::encode`], `application/octet-stream`).
    #[default]
    Binary,
    /// JSON ([`layout::encode_json`], `application/json`), for scripts.
    Json,
}

/// Where a node connects and what it calls its table.
#[derive(Debug, Clone, Default)]
pub struct NetworkOptions {
    /// Endpoints to listen on (`tcp/0.0.0.0:7447`).
    pub listen: Vec<String>,
    /// Endpoints to connect to (`tcp/HOST:7447`).
    pub connect: Vec<String>,
    /// A zenoh configuration file (JSON5), read first; `listen` and `connect` are added to it.
    pub config_file: Option<PathBuf>,
    /// The table's name in the key expressions ([`DEFAULT_TABLE`] when empty).
    pub table: String,
    /// The rows' encoding.
    pub format: WireFormat,
}

impl NetworkOptions {
    /// The table's name, checked as one chunk of a key expression.
    pub fn table(&self) -> Result<&str, ZenohError> {
        let t = if self.table.is_empty() {
            DEFAULT_TABLE
        } else {
            &self.table
        };
        check_chunk("table name", t)?;
        Ok(t)
    }

    /// zenoh's configuration: the file (or zenoh's defaults), then the endpoints. With an
    /// endpoint given and no file, multicast scouting is off: the node talks to the endpoints
    /// it was given only.
    pub fn zenoh_config(&self) -> Result<zenoh::Config, ZenohError> {
        let mut config = match &self.config_file {
            Some(p) => zenoh::Config::from_file(p)
                .map_err(|e| ZenohError::zenoh(format!("zenoh config {}", p.display()), e))?,
            None => zenoh::Config::default(),
        };
        let set = |config: &mut zenoh::Config, key: &str, value: String| {
            config
                .insert_json5(key, &value)
                .map_err(|e| ZenohError::zenoh(format!("setting {key} to {value}"), e))
        };
        for (key, list, option) in [
            ("listen/endpoints", &self.listen, "--zenoh-listen"),
            ("connect/endpoints", &self.connect, "--zenoh-connect"),
        ] {
            for e in list {
                check_endpoint(option, e)?;
            }
            if !list.is_empty() {
                let json = serde_json::to_string(list)
                    .map_err(|e| ZenohError::Invalid(format!("{option}: {e}")))?;
                set(&mut config, key, json)?;
            }
        }
        if self.config_file.is_none() && !(self.listen.is_empty() && self.connect.is_empty()) {
            set(&mut config, "scouting/multicast/enabled", "false".into())?;
        }
        Ok(config)
    }

    /// Opens the zenoh session.
    pub fn open(&self) -> Result<zenoh::Session, ZenohError> {
        let config = self.zenoh_config()?;
        zenoh::open(config)
            .wait()
            .map_err(|e| ZenohError::zenoh("opening the session", e))
    }
}

/// Refuses a name that cannot be one chunk of a key expression.
pub fn check_chunk(what: &str, s: &str) -> Result<(), ZenohError> {
    if s.is_empty() || s.contains(['/', '*', '$', '?', '#', ' ']) || s.chars().any(char::is_control)
    {
        return Err(ZenohError::Invalid(format!(
            "{what} {s:?} cannot be part of a zenoh key expression (empty, or with / * $ ? # or spaces)"
        )));
    }
    Ok(())
}

fn check_endpoint(option: &str, e: &str) -> Result<(), ZenohError> {
    let (proto, addr) = e.split_once('/').unwrap_or(("", ""));
    if !matches!(proto, "tcp" | "udp") || addr.rsplit_once(':').is_none() {
        return Err(ZenohError::Invalid(format!(
            "{option} {e:?}: expected tcp/HOST:PORT or udp/HOST:PORT (this build has the tcp and udp transports)"
        )));
    }
    Ok(())
}

/// Undeclares `subscribers` and closes `session` (errors at closing are of no use to anyone).
pub(crate) fn close_subscribed(
    subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
    session: zenoh::Session,
) {
    for s in subscribers {
        let _ = s.undeclare().wait();
    }
    let _ = session.close().wait();
}

/// `rodtrack/<table>/cam/<camera>/<what>`.
pub fn camera_key(table: &str, camera: &str, what: &str) -> String {
    format!("rodtrack/{table}/cam/{camera}/{what}")
}

/// `rodtrack/<table>/fused/<what>`.
pub fn fused_key(table: &str, what: &str) -> String {
    format!("rodtrack/{table}/fused/{what}")
}

/// A publisher of row messages (and JSON status messages) on one key expression, with its
/// sequence numbers and a reused encoding buffer.
pub struct RowPublisher {
    publisher: Publisher<'static>,
    format: WireFormat,
    seq: AtomicU32,
    /// The message's bytes, and the ball's UDP rows on the way.
    buf: Mutex<(Vec<u8>, Vec<u8>)>,
}

impl RowPublisher {
    /// Declares a publisher on `key`: reliable, blocking rather than dropping when the network
    /// is congested, sent at once (no batching), for the lowest latency.
    pub fn declare(
        session: &zenoh::Session,
        key: String,
        format: WireFormat,
    ) -> Result<RowPublisher, ZenohError> {
        let encoding = match format {
            WireFormat::Binary => Encoding::APPLICATION_OCTET_STREAM,
            WireFormat::Json => Encoding::APPLICATION_JSON,
        };
        let publisher = session
            .declare_publisher(key.clone())
            .encoding(encoding)
            .congestion_control(CongestionControl::Block)
            .express(true)
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("declaring a publisher on {key}"), e))?;
        Ok(RowPublisher {
            publisher,
            format,
            seq: AtomicU32::new(0),
            buf: Mutex::new((Vec::with_capacity(4096), Vec::new())),
        })
    }

    /// Publishes one message of `rows` (all of the header's frame and timestamp; the sequence
    /// number is the publisher's).
    pub fn publish(&self, mut header: Header, rows: &[Measurement]) -> Result<(), ZenohError> {
        header.seq = self.seq.fetch_add(1, Ordering::Relaxed);
        let mut guard = self.buf.lock().unwrap_or_else(|e| e.into_inner());
        let buf = &mut guard.0;
        match self.format {
            WireFormat::Binary => layout::encode(&header, rows, buf)?,
            WireFormat::Json => layout::encode_json(&header, rows, buf)?,
        }
        self.publisher
            .put(buf.as_slice())
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("publishing on {}", self.key()), e))
    }

    /// Publishes the rows of `rows` as one message per run of rows with the same frame and
    /// timestamp, with `kind`, `complete` and `cameras`.
    pub fn publish_runs(
        &self,
        kind: Kind,
        complete: bool,
        cameras: u64,
        rows: &[Measurement],
    ) -> Result<(), ZenohError> {
        let mut first = Ok(());
        for run in rows.chunk_by(|a, b| a.frame == b.frame && a.timestamp_ns == b.timestamp_ns) {
            let header = Header {
                kind,
                seq: 0,
                frame: run[0].frame,
                timestamp_ns: run[0].timestamp_ns,
                complete,
                cameras,
            };
            for chunk in run.chunks(layout::MAX_ROWS) {
                if let Err(e) = self.publish(header, chunk) {
                    if first.is_ok() {
                        first = Err(e);
                    }
                }
            }
        }
        first
    }

    /// Publishes one ball message of `rows` with their uncertainties (`ball_layout`).
    pub fn publish_ball(&self, rows: &[BallRow], sigma_mm: &[f64]) -> Result<(), ZenohError> {
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        let mut guard = self.buf.lock().unwrap_or_else(|e| e.into_inner());
        let (buf, scratch) = &mut *guard;
        match self.format {
            WireFormat::Binary => ball_layout::encode_ball(seq, rows, sigma_mm, scratch, buf)?,
            WireFormat::Json => ball_layout::encode_ball_json(seq, rows, sigma_mm, buf),
        }
        self.publisher
            .put(buf.as_slice())
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("publishing on {}", self.key()), e))
    }

    /// Publishes a JSON text as it is (status messages).
    pub fn publish_text(&self, json: &str) -> Result<(), ZenohError> {
        self.publisher
            .put(json)
            .encoding(Encoding::APPLICATION_JSON)
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("publishing on {}", self.key()), e))
    }

    /// Publishes each event as one JSON message (its line of `--events-out`); `text` is a
    /// buffer kept for its capacity. Every event is tried; the first failure is returned, as
    /// the sinks report it.
    pub fn publish_events(&self, events: &[BallEvent], text: &mut String) -> Result<(), IoError> {
        let mut first = Ok(());
        for e in events {
            text.clear();
            e.push_json(text);
            if let Err(err) = self.publish_text(text) {
                first = first.and(Err(net_error(self.key(), err)));
            }
        }
        first
    }

    /// The key expression.
    pub fn key(&self) -> &str {
        self.publisher.key_expr().as_str()
    }
}

/// A publication's failure as the sinks report it, naming the key expression.
pub(crate) fn net_error(key: &str, e: ZenohError) -> IoError {
    IoError::Net {
        addr: key.to_string(),
        source: std::io::Error::other(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn names_and_endpoints_are_checked_by_option() {
        assert!(check_chunk("camera name", "cam0").is_ok());
        let e = check_chunk("camera name", "cam/0").unwrap_err().to_string();
        assert!(e.contains("cam/0"), "{e}");
        let net = NetworkOptions {
            listen: vec!["127.0.0.1:7447".into()],
            ..Default::default()
        };
        let e = net.zenoh_config().unwrap_err().to_string();
        assert!(
            e.contains("--zenoh-listen") && e.contains("127.0.0.1:7447"),
            "{e}"
        );
        let net = NetworkOptions {
            listen: vec!["tcp/127.0.0.1:7447".into()],
            ..Default::default()
        };
        let c = net.zenoh_config().unwrap();
        let s = c.get_json("listen/endpoints").unwrap();
        assert!(s.contains("tcp/127.0.0.1:7447"), "{s}");
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
    }
}
