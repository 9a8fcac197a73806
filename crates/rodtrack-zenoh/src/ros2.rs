//! ROS 2 over rmw_zenoh: the fused rows (or a camera node's) as `sensor_msgs/msg/JointState`,
//! and the ball as `geometry_msgs/msg/PointStamped` with its velocity as
//! `geometry_msgs/msg/Vector3Stamped`, published the way rmw_zenoh's own publishers do, so
//! that a ROS 2 node on rmw_zenoh (`ros2 topic echo`, a controller) receives them from the
//! same zenoh router.
//!
//! What a publisher of rmw_zenoh (`rmw_zenoh_cpp`, every release of Humble from 0.1.2, Jazzy
//! from 0.2.4, Kilted, Lyrical and Rolling up to 0.12.0 alike) puts on the network, and what
//! this module reproduces:
//! - **the data**, on `<domain>/<topic>/<type>/<hash>` (the topic without its leading and
//!   trailing `/`), the type in its DDS form (`sensor_msgs::msg::dds_::JointState_`) and the
//!   hash as `RIHS01_<64 hex>`; the payload is the message in CDR (XCDR1, little endian, with
//!   its 4-byte encapsulation header);
//! - **an attachment** on every sample: the publication's sequence number (`int64`, from 1),
//!   its source timestamp (`int64`, ns since the epoch when published) and the publisher's
//!   16-byte GID, serialised with zenoh-ext's serializer: two 8-byte little-endian integers,
//!   then the GID as a sequence (its length as LEB128, `0x10`, then the 16 bytes). A
//!   subscriber of rmw_zenoh drops a sample without one;
//! - **liveliness tokens** that put the node and its publisher in the ROS graph
//!   (`ros2 node list`, `ros2 topic list -t`, `ros2 topic info`): the node's
//!   `@ros2_lv/<domain>/<zid>/<node id>/<node id>/NN/<enclave>/<namespace>/<node name>`, the
//!   publisher's `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/MP/...` with, after the node
//!   name, `/<topic>/<type>/<hash>/<qos>`; each `/` inside a name written `%`; a node's
//!   publishers numbered from 1 after the node's own id 0, as rmw_zenoh's context numbers
//!   its entities; the QoS as rmw_zenoh writes it, a field left empty where it equals
//!   rmw_zenoh's default (reliable, volatile, keep last 42, no deadline, lifespan or lease):
//!   `::,:,:,:,,` for these publishers, which use those defaults;
//! - **the GID** is the XXH3 128-bit hash of the publisher's liveliness key expression, its low
//!   64 bits then its high 64 bits, little endian.
//!
//! Nothing here needs ROS: the key expression, the tokens and the attachment are checked by
//! the CI against rmw_zenoh's rules with independent parsers (zenoh's Python deserializer,
//! `rosbags` for the CDR and the type hash, Python's `xxhash`). A ROS 2 install receiving the
//! samples was not run here (docs/network.md).

use crate::ZenohError;
use rodtrack_core::ball::BallRow;
use rodtrack_core::Measurement;
use rodtrack_io::mcap::{ball_place_and_velocity, JointState, StampedXyz};
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

/// `sensor_msgs/msg/JointState` in the DDS form rmw_zenoh puts in key expressions.
pub const JOINT_STATE_DDS_TYPE: &str = "sensor_msgs::msg::dds_::JointState_";
/// The type hash of `sensor_msgs/msg/JointState` (REP 2016, `RIHS01`), the same for ROS 2
/// Humble's and Jazzy's definitions.
pub const JOINT_STATE_TYPE_HASH: &str =
    "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e";
/// A ROS 2 message type as rmw_zenoh names it: its DDS form and its type hash (REP 2016,
/// `RIHS01`; the same for ROS 2 Humble's and Jazzy's definitions of the types below).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ros2Type {
    /// The type in its DDS form (`sensor_msgs::msg::dds_::JointState_`).
    pub dds: &'static str,
    /// The type hash (`RIHS01_<64 hex>`).
    pub hash: &'static str,
}

/// `sensor_msgs/msg/JointState`.
pub const JOINT_STATE: Ros2Type = Ros2Type {
    dds: JOINT_STATE_DDS_TYPE,
    hash: JOINT_STATE_TYPE_HASH,
};
/// `geometry_msgs/msg/PointStamped`.
pub const POINT_STAMPED: Ros2Type = Ros2Type {
    dds: "geometry_msgs::msg::dds_::PointStamped_",
    hash: "RIHS01_4c0296af86e01e562e9e0405d138a01537247580076c58ea38d7923ac1045897",
};
/// `geometry_msgs/msg/Vector3Stamped`.
pub const VECTOR3_STAMPED: Ros2Type = Ros2Type {
    dds: "geometry_msgs::msg::dds_::Vector3Stamped_",
    hash: "RIHS01_d4829622288cbb443886e7ea94ea5671a3b1be6bab4ad04224432a65f7d7887a",
};

/// The QoS part of the publisher's liveliness token: every policy at rmw_zenoh's default.
pub const DEFAULT_QOS_KEYEXPR: &str = "::,:,:,:,,";
/// The liveliness tokens' admin space.
const ADMIN_SPACE: &str = "@ros2_lv";

/// The ROS 2 names of a table's publisher.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2Names {
    /// ROS 2 domain id (`ROS_DOMAIN_ID`).
    pub domain: u32,
    /// The topic: `/rodtrack/<table>/joint_states`.
    pub topic: String,
    /// The node's name: `rodtrack_fusion_<table>`.
    pub node: String,
    /// The joint states' `header.frame_id`: `rodtrack/<table>` (a camera node's:
    /// `rodtrack/<table>/cam/<camera>`).
    pub frame_id: String,
    /// The table frame's id, the ball's `header.frame_id`: `rodtrack/<table>`.
    pub table_frame: String,
}

impl Ros2Names {
    /// The fusion node's names for `table` in `domain`: the topic `/rodtrack/<table>/joint_states`
    /// of the node `rodtrack_fusion_<table>`. The table's name must be a ROS 2 name token
    /// (letters, digits and single underscores, not starting with a digit).
    pub fn fused(domain: u32, table: &str) -> Result<Ros2Names, ZenohError> {
        check_domain(domain)?;
        check_token("table name", "--table, or the recording's", table)?;
        Ok(Ros2Names::under(
            domain,
            format!("rodtrack/{table}"),
            format!("rodtrack_fusion_{table}"),
            table,
        ))
    }

    /// A camera node's names: the topic `/rodtrack/<table>/cam/<camera>/joint_states` of the
    /// node `rodtrack_camera_<table>_<camera>`; the table's and the camera's names must be ROS
    /// 2 name tokens.
    pub fn camera(domain: u32, table: &str, camera: &str) -> Result<Ros2Names, ZenohError> {
        check_domain(domain)?;
        check_token("table name", "--table", table)?;
        check_token("camera name", "the calibration's", camera)?;
        Ok(Ros2Names::under(
            domain,
            format!("rodtrack/{table}/cam/{camera}"),
            format!("rodtrack_camera_{table}_{camera}"),
            table,
        ))
    }

    /// The names of a node whose joint states go on `/<prefix>/joint_states`, with the frame
    /// id `<prefix>`.
    fn under(domain: u32, prefix: String, node: String, table: &str) -> Ros2Names {
        Ros2Names {
            domain,
            topic: format!("/{prefix}/joint_states"),
            node,
            frame_id: prefix,
            table_frame: format!("rodtrack/{table}"),
        }
    }

    /// The ball's topic, `/<prefix>/ball` (`geometry_msgs/msg/PointStamped`).
    pub fn ball_topic(&self) -> String {
        format!("/{}/ball", self.frame_id)
    }

    /// The ball's velocity's topic, `/<prefix>/ball/velocity`
    /// (`geometry_msgs/msg/Vector3Stamped`).
    pub fn ball_velocity_topic(&self) -> String {
        format!("/{}/ball/velocity", self.frame_id)
    }

    /// The joint states' key expression.
    pub fn topic_keyexpr(&self) -> String {
        self.keyexpr_of(&self.topic, JOINT_STATE)
    }

    /// The key expression of the data of `topic`, of type `ty`.
    pub fn keyexpr_of(&self, topic: &str, ty: Ros2Type) -> String {
        format!(
            "{}/{}/{}/{}",
            self.domain,
            strip_slashes(topic),
            ty.dds,
            ty.hash
        )
    }

    /// The node's liveliness token (`NN`), with the session's id and the node's id.
    pub fn node_token(&self, zid: &str, node_id: u64) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{zid}/{node_id}/{node_id}/NN/%/%/{}",
            self.domain,
            mangle(&self.node)
        )
    }

    /// The joint states' publisher's liveliness token (`MP`), with the session's id, the
    /// node's id and the publisher's entity id.
    pub fn publisher_token(&self, zid: &str, node_id: u64, entity_id: u64) -> String {
        self.publisher_token_of(zid, node_id, entity_id, &self.topic, JOINT_STATE)
    }

    /// The liveliness token (`MP`) of a publisher of `topic`, of type `ty`.
    pub fn publisher_token_of(
        &self,
        zid: &str,
        node_id: u64,
        entity_id: u64,
        topic: &str,
        ty: Ros2Type,
    ) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{zid}/{node_id}/{entity_id}/MP/%/%/{}/{}/{}/{}/{DEFAULT_QOS_KEYEXPR}",
            self.domain,
            mangle(&self.node),
            mangle(topic),
            ty.dds,
            ty.hash
        )
    }
}

/// ROS 2's domain ids: 0 to 232 (on Linux); a larger one would be read by no ROS node.
fn check_domain(domain: u32) -> Result<(), ZenohError> {
    if domain > 232 {
        return Err(ZenohError::Invalid(format!(
            "--ros2-domain {domain}: ROS 2 domain ids are 0 to 232"
        )));
    }
    Ok(())
}

/// A name that goes into a ROS 2 topic: letters, digits and single underscores, not starting
/// with a digit.
fn check_token(what: &str, from: &str, name: &str) -> Result<(), ZenohError> {
    let ok = !name.is_empty()
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !name.starts_with(|c: char| c.is_ascii_digit())
        && !name.contains("__");
    if !ok {
        return Err(ZenohError::Invalid(format!(
            "--ros2-domain: {what} {name:?} ({from}) cannot be part of a ROS 2 topic name (letters, digits and single underscores, not starting with a digit)"
        )));
    }
    Ok(())
}

/// A name with each `/` written `%` (rmw_zenoh's `mangle_name`).
fn mangle(s: &str) -> String {
    s.replace('/', "%")
}

/// One leading and one trailing `/` removed (rmw_zenoh's `strip_slashes`).
fn strip_slashes(s: &str) -> &str {
    let s = s.strip_prefix('/').unwrap_or(s);
    s.strip_suffix('/').unwrap_or(s)
}

/// The GID rmw_zenoh gives the entity of a liveliness key expression: its XXH3 128-bit hash,
/// the low 64 bits then the high 64 bits, each little endian.
pub fn gid_of(token: &str) -> [u8; 16] {
    xxhash_rust::xxh3::xxh3_128(token.as_bytes()).to_le_bytes()
}

/// The attachment's length: two `int64` and the GID as a sequence of 16 bytes.
pub const ATTACHMENT_LEN: usize = 8 + 8 + 1 + 16;

/// A sample's attachment as rmw_zenoh reads it (`AttachmentData`): `sequence_number`,
/// `source_timestamp` (ns) and the GID, in zenoh-ext's serialization.
pub fn attachment(
    sequence_number: i64,
    source_timestamp_ns: i64,
    gid: &[u8; 16],
) -> [u8; ATTACHMENT_LEN] {
    let mut a = [0u8; ATTACHMENT_LEN];
    a[..8].copy_from_slice(&sequence_number.to_le_bytes());
    a[8..16].copy_from_slice(&source_timestamp_ns.to_le_bytes());
    // The sequence's length in LEB128: 16 fits one byte.
    a[16] = 16;
    a[17..].copy_from_slice(gid);
    a
}

/// A ROS 2 node in the graph: its liveliness token (`NN`, node id 0), held while it or any of
/// its publishers lives, and the entity ids its publishers take (1, 2, ...).
pub struct Ros2Node {
    names: Ros2Names,
    zid: String,
    _token: LivelinessToken,
    next_entity: AtomicU64,
}

/// The node's id in its tokens: a node's process holds one node.
const NODE_ID: u64 = 0;

impl Ros2Node {
    /// Declares the node's token on `session`.
    pub fn declare(
        session: &zenoh::Session,
        names: &Ros2Names,
    ) -> Result<Arc<Ros2Node>, ZenohError> {
        let zid = session.zid().to_string();
        let token = declare_token(session, &names.node_token(&zid, NODE_ID))?;
        Ok(Arc::new(Ros2Node {
            names: names.clone(),
            zid,
            _token: token,
            next_entity: AtomicU64::new(NODE_ID + 1),
        }))
    }

    /// The node's names.
    pub fn names(&self) -> &Ros2Names {
        &self.names
    }
}

fn declare_token(session: &zenoh::Session, key: &str) -> Result<LivelinessToken, ZenohError> {
    session
        .liveliness()
        .declare_token(key.to_string())
        .wait()
        .map_err(|e| ZenohError::zenoh(format!("declaring the ROS 2 liveliness token {key}"), e))
}

/// One topic's publisher of a [`Ros2Node`]: its liveliness token, its GID and its sequence.
struct Ros2Topic {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    _node: Arc<Ros2Node>,
    gid: [u8; 16],
    seq: AtomicI64,
}

impl Ros2Topic {
    fn declare(
        session: &zenoh::Session,
        node: &Arc<Ros2Node>,
        topic: &str,
        ty: Ros2Type,
    ) -> Result<Ros2Topic, ZenohError> {
        let entity_id = node.next_entity.fetch_add(1, Ordering::Relaxed);
        let token_key = node
            .names
            .publisher_token_of(&node.zid, NODE_ID, entity_id, topic, ty);
        let token = declare_token(session, &token_key)?;
        let key = node.names.keyexpr_of(topic, ty);
        // Reliable (zenoh's default), as rmw_zenoh's publishers of the default QoS. It blocks
        // rather than drops when the network is congested, as rodtrack's own publishers on the
        // same links do (rmw_zenoh's keep-last publishers drop): zenoh discards a droppable
        // message still queued when the session closes, and a node's last message was lost
        // that way at its end.
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Block)
            .express(true)
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("declaring the ROS 2 publisher on {key}"), e))?;
        Ok(Ros2Topic {
            publisher,
            _token: token,
            _node: node.clone(),
            gid: gid_of(&token_key),
            seq: AtomicI64::new(1),
        })
    }

    /// Puts one message (CDR) with its attachment.
    fn put(&self, cdr: &[u8]) -> Result<(), ZenohError> {
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX));
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        self.publisher
            .put(cdr)
            .attachment(attachment(seq, now_ns, &self.gid).as_slice())
            .wait()
            .map_err(|e| {
                ZenohError::zenoh(format!("publishing on {}", self.publisher.key_expr()), e)
            })
    }
}

/// Publishes fused rows as `sensor_msgs/msg/JointState` for ROS 2 over rmw_zenoh, on the
/// node's joint states topic.
pub struct Ros2Publisher {
    topic: Ros2Topic,
    frame_id: String,
    cdr: Mutex<Vec<u8>>,
}

impl Ros2Publisher {
    /// Declares the joint states' publisher of `node` on `session`.
    pub fn declare(
        session: &zenoh::Session,
        node: &Arc<Ros2Node>,
    ) -> Result<Ros2Publisher, ZenohError> {
        Ok(Ros2Publisher {
            topic: Ros2Topic::declare(session, node, &node.names.topic, JOINT_STATE)?,
            frame_id: node.names.frame_id.clone(),
            cdr: Mutex::new(Vec::with_capacity(1024)),
        })
    }

    /// Publishes one joint state of `rows` (one frame set's fused rows), stamped with their
    /// capture time.
    pub fn publish(&self, rows: &[Measurement]) -> Result<(), ZenohError> {
        let Some(first) = rows.first() else {
            return Ok(());
        };
        let mut cdr = self.cdr.lock().unwrap_or_else(|e| e.into_inner());
        JointState::rows_to_cdr(
            rows.iter(),
            first.timestamp_ns.as_nanos(),
            &self.frame_id,
            &mut cdr,
        );
        self.topic.put(&cdr)
    }

    /// Publishes one joint state per frame of `rows` (runs of rows with the same frame and
    /// timestamp); the first error, after trying every frame.
    pub fn publish_frames(&self, rows: &[Measurement]) -> Result<(), ZenohError> {
        let mut first = Ok(());
        for run in rows.chunk_by(|a, b| a.frame == b.frame && a.timestamp_ns == b.timestamp_ns) {
            if let Err(e) = self.publish(run) {
                if first.is_ok() {
                    first = Err(e);
                }
            }
        }
        first
    }

    /// The data's key expression.
    pub fn key(&self) -> &str {
        self.topic.publisher.key_expr().as_str()
    }

    /// The publisher's GID (as in its samples' attachments).
    pub fn gid(&self) -> [u8; 16] {
        self.topic.gid
    }
}

/// Publishes a ball's rows for ROS 2 over rmw_zenoh: its centre as
/// `geometry_msgs/msg/PointStamped` on `/<prefix>/ball` (m, the table frame: `z` the ball's
/// radius above the field) and its velocity as `geometry_msgs/msg/Vector3Stamped` on
/// `/<prefix>/ball/velocity` (m/s), both stamped with the frame's capture time and with the
/// table frame's id. Only rows with a place go out, `ok` (seen) and `predicted` (a short
/// occlusion, the filter's prediction); `lost` and `conflict` (cameras that disagree) rows
/// send nothing, and the topics fall silent. The row's status stays on rodtrack's own key.
pub struct Ros2BallPublisher {
    position: Ros2Topic,
    velocity: Ros2Topic,
    frame_id: String,
    centre_z_m: f64,
    cdr: Mutex<Vec<u8>>,
}

impl Ros2BallPublisher {
    /// Declares the ball's two publishers of `node` on `session`, for a ball of
    /// `diameter_mm`.
    pub fn declare(
        session: &zenoh::Session,
        node: &Arc<Ros2Node>,
        diameter_mm: f64,
    ) -> Result<Ros2BallPublisher, ZenohError> {
        if !(diameter_mm.is_finite() && diameter_mm > 0.0) {
            return Err(ZenohError::Invalid(format!(
                "--ros2-domain: the ball's diameter {diameter_mm} mm is not a positive number"
            )));
        }
        let n = &node.names;
        Ok(Ros2BallPublisher {
            position: Ros2Topic::declare(session, node, &n.ball_topic(), POINT_STAMPED)?,
            velocity: Ros2Topic::declare(session, node, &n.ball_velocity_topic(), VECTOR3_STAMPED)?,
            frame_id: n.table_frame.clone(),
            centre_z_m: diameter_mm * 0.5e-3,
            cdr: Mutex::new(Vec::with_capacity(64)),
        })
    }

    /// Publishes `row` (its place, then its velocity) if it has a place; `Ok(false)` for a
    /// row that sends nothing.
    pub fn publish(&self, row: &BallRow) -> Result<bool, ZenohError> {
        let Some((p, v)) = ball_place_and_velocity(row, self.centre_z_m) else {
            return Ok(false);
        };
        let time_ns = row.timestamp_ns.as_nanos();
        let mut cdr = self.cdr.lock().unwrap_or_else(|e| e.into_inner());
        StampedXyz::write_cdr(time_ns, &self.frame_id, p, &mut cdr);
        let first = self.position.put(&cdr);
        StampedXyz::write_cdr(time_ns, &self.frame_id, v, &mut cdr);
        let second = self.velocity.put(&cdr);
        first.and(second).map(|()| true)
    }

    /// The key expression of the ball's place (its velocity's is beside it).
    pub fn key(&self) -> &str {
        self.position.publisher.key_expr().as_str()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn key_expressions_and_tokens_follow_rmw_zenoh() {
        let n = Ros2Names::fused(0, "lab").unwrap();
        assert_eq!(
            n.topic_keyexpr(),
            format!("0/rodtrack/lab/joint_states/sensor_msgs::msg::dds_::JointState_/{JOINT_STATE_TYPE_HASH}")
        );
        assert_eq!(
            n.node_token("abc1", 0),
            "@ros2_lv/0/abc1/0/0/NN/%/%/rodtrack_fusion_lab"
        );
        let t = n.publisher_token("abc1", 0, 1);
        let parts: Vec<&str> = t.split('/').collect();
        // rmw_zenoh's KeyexprIndex: AdminSpace .. TopicQoS, 13 parts.
        assert_eq!(parts.len(), 13, "{t}");
        assert_eq!(parts[5], "MP");
        assert_eq!(parts[9], "%rodtrack%lab%joint_states");
        assert_eq!(parts[12].split(':').count(), 6);
        for bad in ["", "2lab", "la b", "la__b", "lab/x", "läb"] {
            let e = Ros2Names::fused(0, bad).unwrap_err().to_string();
            assert!(e.contains("--table") && e.contains("--ros2-domain"), "{e}");
        }
        let e = Ros2Names::fused(233, "lab").unwrap_err().to_string();
        assert!(e.contains("--ros2-domain 233"), "{e}");
        let c = Ros2Names::camera(0, "lab", "cam0").unwrap();
        assert_eq!(c.topic, "/rodtrack/lab/cam/cam0/joint_states");
        assert_eq!(c.node, "rodtrack_camera_lab_cam0");
        let t = c.publisher_token("abc1", 0, 1);
        assert_eq!(t.split('/').count(), 13, "{t}");
        assert!(t.contains("/%rodtrack%lab%cam%cam0%joint_states/"), "{t}");
        let e = Ros2Names::camera(0, "lab", "cam-0")
            .unwrap_err()
            .to_string();
        assert!(e.contains("camera name \"cam-0\""), "{e}");
    }

    #[test]
    fn the_ball_goes_on_its_own_topics_of_the_same_node() {
        let n = Ros2Names::camera(2, "lab", "cam1").unwrap();
        assert_eq!(n.ball_topic(), "/rodtrack/lab/cam/cam1/ball");
        assert_eq!(n.table_frame, "rodtrack/lab");
        assert_eq!(
            n.keyexpr_of(&n.ball_velocity_topic(), VECTOR3_STAMPED),
            format!("2/rodtrack/lab/cam/cam1/ball/velocity/geometry_msgs::msg::dds_::Vector3Stamped_/{}", VECTOR3_STAMPED.hash)
        );
        let t = n.publisher_token_of("abc1", 0, 2, &n.ball_topic(), POINT_STAMPED);
        let parts: Vec<&str> = t.split('/').collect();
        assert_eq!(parts.len(), 13, "{t}");
        assert_eq!((parts[3], parts[4], parts[5]), ("0", "2", "MP"));
        assert_eq!(parts[8], "rodtrack_camera_lab_cam1");
        assert_eq!(parts[9], "%rodtrack%lab%cam%cam1%ball");
        assert_eq!(parts[10], "geometry_msgs::msg::dds_::PointStamped_");
        // The joint states' token is the generic one's.
        assert_eq!(
            n.publisher_token("abc1", 0, 1),
            n.publisher_token_of("abc1", 0, 1, &n.topic, JOINT_STATE)
        );
        assert_eq!(
            Ros2Names::fused(0, "lab").unwrap().ball_topic(),
            "/rodtrack/lab/ball"
        );
    }

    #[test]
    fn the_attachment_is_zenoh_ext_serialized() {
        let gid: [u8; 16] = core::array::from_fn(|i| i as u8 + 1);
        let a = attachment(0x0102, -2, &gid);
        assert_eq!(&a[..8], &[2, 1, 0, 0, 0, 0, 0, 0]);
        assert_eq!(&a[8..16], &[0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff]);
        assert_eq!(a[16], 16);
        assert_eq!(&a[17..], &gid);
    }

    #[test]
    fn the_gid_is_xxh3_128_low_half_first() {
        // XXH3-128 of the empty input: 99aa06d3014798d8 6001c324468d497f (high, low).
        let g = gid_of("");
        assert_eq!(&g[..8], &0x6001c324468d497fu64.to_le_bytes());
        assert_eq!(&g[8..], &0x99aa06d3014798d8u64.to_le_bytes());
    }
}
