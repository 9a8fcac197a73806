//! A remote console's view of a table: one subscriber to every node's rows, statuses,
//! previews and ball rows (`rodtrack console --subscribe zenoh`).
//!
//! Subscribed key expressions (`<table>` from the options):
//! `rodtrack/<table>/cam/*/rows`, `.../cam/*/status`, `.../cam/*/preview`, `.../cam/*/ball`,
//! `.../cam/*/events`, `rodtrack/<table>/fused/rows`, `.../fused/status`, `.../fused/ball`, `.../fused/events`. Each
//! message is decoded and handed to
//! the callback as a [`NodeEvent`]; a message that does not decode (or a row message of the
//! wrong kind, a status that is not a JSON object) is a [`NodeEvent::Malformed`], counted,
//! never a panic.

use crate::ball_layout::decode_ball;
use crate::layout::{decode, Kind, Message};
use crate::net::{camera_key, fused_key, NetworkOptions};
use crate::preview::{decode_preview, PreviewMessage};
use crate::ZenohError;
use rodtrack_core::ball::events::BallEvent;
use rodtrack_core::ball::BallRow;
use rodtrack_core::CameraId;
use rodtrack_io::parse_event_json;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use zenoh::pubsub::Subscriber;
use zenoh::Wait;

/// A node of the table: a camera node (by its camera's name) or the fusion node.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub enum Node {
    /// The camera node of the camera of this name.
    Camera(String),
    /// The fusion node.
    Fusion,
}

impl Node {
    /// `cam/<camera>` or `fused`: the node's part of its key expressions.
    pub fn label(&self) -> String {
        match self {
            Node::Camera(name) => format!("cam/{name}"),
            Node::Fusion => "fused".into(),
        }
    }
}

/// What came from the network.
#[derive(Debug)]
pub enum NodeEvent<'a> {
    /// A camera's filtered rows (kind [`Kind::CameraRows`]) or fused rows ([`Kind::Fused`]).
    Rows {
        /// The key expression it came on.
        key: &'a str,
        /// Its node.
        node: Node,
        /// The message.
        message: Message,
    },
    /// A node's status (a JSON object, as the node published it).
    Status {
        /// The key expression it came on.
        key: &'a str,
        /// Its node.
        node: Node,
        /// The status.
        status: serde_json::Value,
    },
    /// A frame's ball rows: a camera node's own row, or the fusion node's (the cameras' rows,
    /// then the fused one).
    Ball {
        /// The key expression it came on.
        key: &'a str,
        /// Its node.
        node: Node,
        /// The rows.
        rows: Vec<BallRow>,
    },
    /// One of the ball's events, as a line of `--events-out`: the fusion node's, or a camera
    /// node's (`track --publish zenoh --zenoh-events`: its camera alone).
    Event {
        /// The key expression it came on.
        key: &'a str,
        /// Its node.
        node: Node,
        /// The event.
        event: BallEvent,
    },
    /// A camera's preview frame.
    Preview {
        /// The key expression it came on.
        key: &'a str,
        /// Its node.
        node: Node,
        /// The preview.
        preview: PreviewMessage,
    },
    /// A message that could not be used.
    Malformed {
        /// The key expression it came on.
        key: &'a str,
        /// Why.
        error: ZenohError,
        /// Malformed messages so far, this one included.
        count: u64,
    },
}

/// What the monitor calls for each message.
type OnEvent = Arc<dyn Fn(NodeEvent<'_>) + Send + Sync>;

/// The subscribers to a table's nodes and their zenoh session. Dropped or
/// [closed](Monitor::close), it stops.
pub struct Monitor {
    // Declared before the session so that they are undeclared first.
    subscribers: Vec<Subscriber<()>>,
    session: zenoh::Session,
    malformed: Arc<AtomicU64>,
}

/// What a key expression's last chunks say.
#[derive(Clone, Copy)]
enum What {
    Rows,
    Status,
    Preview,
    Ball,
    Event,
}

impl Monitor {
    /// Opens a session with `net`'s endpoints and subscribes to every node of `net`'s table.
    /// `on_event` runs in zenoh's threads, once per message: it should return quickly.
    pub fn open<F>(net: &NetworkOptions, on_event: F) -> Result<Monitor, ZenohError>
    where
        F: Fn(NodeEvent<'_>) + Send + Sync + 'static,
    {
        let table = net.table()?.to_string();
        let session = net.open()?;
        let on_event: OnEvent = Arc::new(on_event);
        let malformed = Arc::new(AtomicU64::new(0));
        let mut subscribers = Vec::new();
        for (key, what) in [
            (camera_key(&table, "*", "rows"), What::Rows),
            (camera_key(&table, "*", "status"), What::Status),
            (camera_key(&table, "*", "preview"), What::Preview),
            (camera_key(&table, "*", "ball"), What::Ball),
            (camera_key(&table, "*", "events"), What::Event),
            (fused_key(&table, "rows"), What::Rows),
            (fused_key(&table, "status"), What::Status),
            (fused_key(&table, "ball"), What::Ball),
            (fused_key(&table, "events"), What::Event),
        ] {
            let (on_event, malformed) = (on_event.clone(), malformed.clone());
            let subscriber = session
                .declare_subscriber(key.clone())
                .callback(move |sample| {
                    let key = sample.key_expr().as_str();
                    let bytes = sample.payload().to_bytes();
                    let event = match interpret(key, what, &bytes) {
                        Ok(e) => e,
                        Err(error) => NodeEvent::Malformed {
                            key,
                            error,
                            count: malformed.fetch_add(1, Ordering::Relaxed) + 1,
                        },
                    };
                    on_event(event);
                })
                .wait()
                .map_err(|e| ZenohError::zenoh(format!("declaring a subscriber on {key}"), e))?;
            subscribers.push(subscriber);
        }
        Ok(Monitor {
            subscribers,
            session,
            malformed,
        })
    }

    /// The key expressions subscribed to.
    pub fn keys(&self) -> Vec<&str> {
        self.subscribers
            .iter()
            .map(|s| s.key_expr().as_str())
            .collect()
    }

    /// Malformed messages so far.
    pub fn malformed(&self) -> u64 {
        self.malformed.load(Ordering::Relaxed)
    }

    /// Undeclares the subscribers and closes the session.
    pub fn close(self) {
        let Monitor {
            subscribers,
            session,
            ..
        } = self;
        crate::net::close_subscribed(subscribers, session);
    }
}

/// The node of a key expression `rodtrack/<table>/cam/<camera>/<what>` or
/// `rodtrack/<table>/fused/<what>`.
fn node_of(key: &str) -> Result<Node, ZenohError> {
    let parts: Vec<&str> = key.split('/').collect();
    match parts.as_slice() {
        ["rodtrack", _, "cam", camera, _] => Ok(Node::Camera((*camera).to_string())),
        ["rodtrack", _, "fused", _] => Ok(Node::Fusion),
        _ => Err(ZenohError::Message(format!(
            "key expression {key} is not a node's"
        ))),
    }
}

fn interpret<'a>(key: &'a str, what: What, bytes: &[u8]) -> Result<NodeEvent<'a>, ZenohError> {
    let node = node_of(key)?;
    Ok(match what {
        What::Rows => {
            let message = decode(bytes)?;
            let expected = match node {
                Node::Camera(_) => Kind::CameraRows,
                Node::Fusion => Kind::Fused,
            };
            if message.header.kind != expected {
                return Err(ZenohError::Message(format!(
                    "a `{}` message where `{}` messages go",
                    message.header.kind.name(),
                    expected.name()
                )));
            }
            NodeEvent::Rows { key, node, message }
        }
        What::Status => {
            let status: serde_json::Value = serde_json::from_slice(bytes)
                .map_err(|e| ZenohError::Message(format!("status JSON: {e}")))?;
            if !status.is_object() {
                return Err(ZenohError::Message(
                    "a status that is not a JSON object".into(),
                ));
            }
            NodeEvent::Status { key, node, status }
        }
        What::Ball => {
            let rows: Vec<BallRow> = decode_ball(bytes)?.rows.into_iter().map(|r| r.0).collect();
            // A camera node sends its own rows only; the fusion node ends with the fused one.
            let fits = match &node {
                Node::Camera(_) => rows.iter().all(|r| r.camera != CameraId::Fused),
                Node::Fusion => rows.last().is_some_and(|r| r.camera == CameraId::Fused),
            };
            if !fits || rows.is_empty() {
                return Err(ZenohError::Message(format!(
                    "ball rows that are not the {}'s",
                    match node {
                        Node::Camera(_) => "camera node",
                        Node::Fusion => "fusion node",
                    }
                )));
            }
            NodeEvent::Ball { key, node, rows }
        }
        What::Event => {
            let text = std::str::from_utf8(bytes)
                .map_err(|_| ZenohError::Message("an event that is not UTF-8 text".into()))?;
            let event = parse_event_json(text, Path::new(key), 1)
                .map_err(|e| ZenohError::Message(format!("event: {e}")))?;
            NodeEvent::Event { key, node, event }
        }
        What::Preview => {
            if matches!(node, Node::Fusion) {
                return Err(ZenohError::Message("a preview of the fusion node".into()));
            }
            NodeEvent::Preview {
                key,
                node,
                preview: decode_preview(bytes)?,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn messages_are_told_apart_by_key_and_refused_by_reason() {
        assert_eq!(
            node_of("rodtrack/t/cam/cam0/rows").unwrap(),
            Node::Camera("cam0".into())
        );
        assert_eq!(node_of("rodtrack/t/fused/status").unwrap(), Node::Fusion);
        let e = |key: &str, what, b: &[u8]| match interpret(key, what, b) {
            Err(e) => e.to_string(),
            Ok(ev) => panic!("{ev:?}"),
        };
        assert!(e("rodtrack/t/cam/c/status", What::Status, b"[1]").contains("not a JSON object"));
        assert!(e("rodtrack/t/cam/c/status", What::Status, b"{").contains("status JSON"));
        assert!(e("rodtrack/t/cam/c/preview", What::Preview, b"RTZP").contains("shorter"));
        assert!(e("rodtrack/t/cam/c/rows", What::Rows, b"xx").contains("shorter"));
        let mut fused = Vec::new();
        let header = crate::layout::Header {
            kind: Kind::Fused,
            seq: 0,
            frame: 1,
            timestamp_ns: rodtrack_core::Timestamp(5),
            complete: true,
            cameras: 3,
        };
        crate::layout::encode(&header, &[], &mut fused).unwrap();
        assert!(e("rodtrack/t/cam/c/rows", What::Rows, &fused).contains("`fused` message"));
        match interpret("rodtrack/t/fused/rows", What::Rows, &fused).unwrap() {
            NodeEvent::Rows { node, message, .. } => {
                assert_eq!((node, message.header.frame), (Node::Fusion, 1));
            }
            ev => panic!("{ev:?}"),
        }
        // Ball rows: a camera node's own, the fusion node's ending with the fused one.
        let t = rodtrack_core::Timestamp(5);
        let cam = BallRow::lost(1, t, CameraId::Camera(0));
        let fused_row = BallRow::lost(1, t, CameraId::Fused);
        let ball = |rows: &[BallRow]| {
            let mut b = Vec::new();
            crate::ball_layout::encode_ball(0, rows, &[], &mut Vec::new(), &mut b).unwrap();
            b
        };
        for (key, rows) in [
            ("rodtrack/t/cam/c/ball", vec![cam]),
            ("rodtrack/t/fused/ball", vec![cam, fused_row]),
        ] {
            match interpret(key, What::Ball, &ball(&rows)).unwrap() {
                NodeEvent::Ball { rows: got, .. } => assert_eq!(got, rows),
                ev => panic!("{ev:?}"),
            }
        }
        for (key, rows) in [
            ("rodtrack/t/cam/c/ball", vec![fused_row]),
            ("rodtrack/t/fused/ball", vec![fused_row, cam]),
            ("rodtrack/t/fused/ball", vec![]),
        ] {
            assert!(
                e(key, What::Ball, &ball(&rows)).contains("ball rows that are not"),
                "{key}"
            );
        }
        assert!(e("rodtrack/t/fused/ball", What::Ball, b"xx").contains("ball message"));
        // Events: the fusion node's, each a line of `--events-out`.
        let goal = br#"{"frame":93,"timestamp_s":0.465000,"event":"goal","side":"a","goal":"b","score":[1,0]}"#;
        match interpret("rodtrack/t/fused/events", What::Event, goal).unwrap() {
            NodeEvent::Event { event, .. } => {
                assert_eq!(event.frame, 93);
                assert_eq!(event.kind.name(), "goal");
            }
            ev => panic!("{ev:?}"),
        }
        match interpret("rodtrack/t/cam/c/events", What::Event, goal).unwrap() {
            NodeEvent::Event { node, event, .. } => {
                assert_eq!(node, Node::Camera("c".into()));
                assert_eq!(event.frame, 93);
            }
            ev => panic!("{ev:?}"),
        }
        assert!(e("rodtrack/t/fused/events", What::Event, b"{\"frame\":1}").contains("event:"));
        assert!(e("rodtrack/t/fused/events", What::Event, &[0xff, 0xfe]).contains("UTF-8"));
    }
}
