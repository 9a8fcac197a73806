//! ROS 2 over rmw_zenoh: the fused rows (or a camera node's) as `sensor_msgs/msg/JointState`,
//! published the way rmw_zenoh's own publishers do, so that a ROS 2 node on rmw_zenoh
//! (`ros2 topic echo`, a controller) receives them from the same zenoh router.
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
//!   name, `/<topic>/<type>/<hash>/<qos>`; each `/` inside a name written `%`; the QoS as
//!   rmw_zenoh writes it, a field left empty where it equals rmw_zenoh's default (reliable,
//!   volatile, keep last 42, no deadline, lifespan or lease): `::,:,:,:,,` for this publisher,
//!   which uses those defaults;
//! - **the GID** is the XXH3 128-bit hash of the publisher's liveliness key expression, its low
//!   64 bits then its high 64 bits, little endian.
//!
//! Nothing here needs ROS: the key expression, the tokens and the attachment are checked by
//! the CI against rmw_zenoh's rules with independent parsers (zenoh's Python deserializer,
//! `rosbags` for the CDR and the type hash, Python's `xxhash`). A ROS 2 install receiving the
//! samples was not run here (docs/network.md).

use crate::ZenohError;
use rodtrack_core::Measurement;
use rodtrack_io::mcap::JointState;
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::Mutex;
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
    /// The messages' `header.frame_id`: `rodtrack/<table>`.
    pub frame_id: String,
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
        ))
    }

    /// The names of a node whose joint states go on `/<prefix>/joint_states`, with the frame
    /// id `<prefix>`.
    fn under(domain: u32, prefix: String, node: String) -> Ros2Names {
        Ros2Names {
            domain,
            topic: format!("/{prefix}/joint_states"),
            node,
            frame_id: prefix,
        }
    }

    /// The data's key expression.
    pub fn topic_keyexpr(&self) -> String {
        format!(
            "{}/{}/{JOINT_STATE_DDS_TYPE}/{JOINT_STATE_TYPE_HASH}",
            self.domain,
            strip_slashes(&self.topic)
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

    /// The publisher's liveliness token (`MP`), with the session's id, the node's id and the
    /// publisher's entity id.
    pub fn publisher_token(&self, zid: &str, node_id: u64, entity_id: u64) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{zid}/{node_id}/{entity_id}/MP/%/%/{}/{}/{JOINT_STATE_DDS_TYPE}/{JOINT_STATE_TYPE_HASH}/{DEFAULT_QOS_KEYEXPR}",
            self.domain,
            mangle(&self.node),
            mangle(&self.topic)
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

/// Publishes fused rows as `sensor_msgs/msg/JointState` for ROS 2 over rmw_zenoh, with the
/// node's and the publisher's liveliness tokens held while it lives.
pub struct Ros2Publisher {
    publisher: Publisher<'static>,
    _tokens: [LivelinessToken; 2],
    gid: [u8; 16],
    seq: AtomicI64,
    frame_id: String,
    cdr: Mutex<Vec<u8>>,
}

impl Ros2Publisher {
    /// Declares the publisher and its tokens on `session`.
    pub fn declare(
        session: &zenoh::Session,
        names: &Ros2Names,
    ) -> Result<Ros2Publisher, ZenohError> {
        let zid = session.zid().to_string();
        let (node_id, entity_id) = (0, 1);
        let node_token = names.node_token(&zid, node_id);
        let pub_token = names.publisher_token(&zid, node_id, entity_id);
        let key = names.topic_keyexpr();
        let declare_token = |k: &str| {
            session
                .liveliness()
                .declare_token(k.to_string())
                .wait()
                .map_err(|e| {
                    ZenohError::zenoh(format!("declaring the ROS 2 liveliness token {k}"), e)
                })
        };
        let tokens = [declare_token(&node_token)?, declare_token(&pub_token)?];
        // As rmw_zenoh's publisher of a reliable, keep-last topic (zenoh's publishers are
        // reliable by default).
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Drop)
            .express(true)
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("declaring the ROS 2 publisher on {key}"), e))?;
        Ok(Ros2Publisher {
            publisher,
            _tokens: tokens,
            gid: gid_of(&pub_token),
            seq: AtomicI64::new(1),
            frame_id: names.frame_id.clone(),
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
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX));
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        self.publisher
            .put(cdr.as_slice())
            .attachment(attachment(seq, now_ns, &self.gid).as_slice())
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("publishing on {}", self.key()), e))
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
        self.publisher.key_expr().as_str()
    }

    /// The publisher's GID (as in its samples' attachments).
    pub fn gid(&self) -> [u8; 16] {
        self.gid
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
