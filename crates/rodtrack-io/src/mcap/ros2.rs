//! ROS 2 in MCAP: `sensor_msgs/msg/JointState` in CDR, its `ros2msg` schema, and the channel
//! metadata of the `ros2` profile (what rosbag2's MCAP storage writes and reads).
//!
//! CDR here is XCDR1 ("plain CDR") little endian, as ROS 2's middlewares send it: a 4-byte
//! encapsulation header `00 01 00 00` (CDR_LE), then the fields in order, each aligned to its
//! own size (at most 8) counted from the end of the header. A `string` is a `u32` length that
//! counts its NUL, the bytes and the NUL; a sequence is a `u32` count then its elements
//! (`float64` elements 8-byte aligned, no padding when the sequence is empty). Nothing is
//! padded after the last field.

use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::{Measurement, Status};

/// The joint states' schema name (ROS 2's `sensor_msgs/msg/JointState`).
pub const JOINT_STATE_SCHEMA_NAME: &str = "sensor_msgs/msg/JointState";

/// The definitions a stamped message uses, appended as rosbag2 writes them (a line of 80 `=`,
/// `MSG: package/Type`, its definition): `std_msgs/Header` and `builtin_interfaces/Time`.
macro_rules! header_definitions {
    () => {
        "\n\
================================================================================\n\
MSG: std_msgs/Header\n\
builtin_interfaces/Time stamp\n\
string frame_id\n\
\n\
================================================================================\n\
MSG: builtin_interfaces/Time\n\
int32 sec\n\
uint32 nanosec\n"
    };
}

/// A stamped message of three `float64` (`x`, `y`, `z`): its field `field` of type
/// `geometry_msgs/<ty>`, then the definitions it uses.
macro_rules! stamped_xyz_definition {
    ($ty:literal, $field:literal) => {
        concat!(
            "std_msgs/Header header\ngeometry_msgs/",
            $ty,
            " ",
            $field,
            "\n",
            header_definitions!(),
            "\n\
================================================================================\n\
MSG: geometry_msgs/",
            $ty,
            "\nfloat64 x\nfloat64 y\nfloat64 z\n"
        )
    };
}

/// The joint state's message definition in ROS 2's `.msg` language, with the types it uses
/// appended as rosbag2 writes them. Comments are left out: the fields are those of ROS 2's
/// `common_interfaces` and `rcl_interfaces`.
pub const JOINT_STATE_MSGDEF: &str = concat!(
    "std_msgs/Header header\n\
\n\
string[] name\n\
float64[] position\n\
float64[] velocity\n\
float64[] effort\n",
    header_definitions!()
);

/// `geometry_msgs/msg/PointStamped`'s schema name.
pub const POINT_STAMPED_SCHEMA_NAME: &str = "geometry_msgs/msg/PointStamped";

/// `geometry_msgs/msg/PointStamped`'s definition, with the types it uses appended.
pub const POINT_STAMPED_MSGDEF: &str = stamped_xyz_definition!("Point", "point");

/// `geometry_msgs/msg/Vector3Stamped`'s schema name.
pub const VECTOR3_STAMPED_SCHEMA_NAME: &str = "geometry_msgs/msg/Vector3Stamped";

/// `geometry_msgs/msg/Vector3Stamped`'s definition, with the types it uses appended.
pub const VECTOR3_STAMPED_MSGDEF: &str = stamped_xyz_definition!("Vector3", "vector");

/// A ball row as ROS 2 messages: its centre (m, the table frame, `z` = `centre_z_m`: the
/// ball's radius above the field) and its velocity (m/s, `z` 0), when it has a place
/// (`ok`, `predicted`) and both are finite. A `lost` or `conflict` row has none.
pub fn ball_place_and_velocity(row: &BallRow, centre_z_m: f64) -> Option<([f64; 3], [f64; 3])> {
    let (p, v) = (
        [row.x_mm * 1e-3, row.y_mm * 1e-3, centre_z_m],
        [row.vx_mm_s * 1e-3, row.vy_mm_s * 1e-3, 0.0],
    );
    let placed = matches!(row.status, BallStatus::Ok | BallStatus::Predicted);
    (placed && p.iter().chain(&v).all(|x| x.is_finite())).then_some((p, v))
}

/// The `offered_qos_profiles` of the joint state channels (required by the MCAP `ros2`
/// profile): one publisher, reliable, volatile, keep last 10, with rmw's default deadline,
/// lifespan and liveliness; the policies as rmw's enum numbers (rosbags reads numbers or
/// names; rosbag2 itself was not run on these files).
pub const JOINT_STATE_QOS: &str = "- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n  avoid_ros_namespace_conventions: false";

/// The CDR encapsulation header: plain CDR, little endian, no options.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointState {
    /// `header.stamp.sec`, s.
    pub stamp_sec: i32,
    /// `header.stamp.nanosec`, ns.
    pub stamp_nanosec: u32,
    /// `header.frame_id`.
    pub frame_id: String,
    /// The joints' names.
    pub name: Vec<String>,
    /// Positions: m for a slide, rad for a turn.
    pub position: Vec<f64>,
    /// Velocities: m/s, rad/s.
    pub velocity: Vec<f64>,
    /// Efforts (rodtrack leaves them empty).
    pub effort: Vec<f64>,
}

impl JointState {
    /// The stamp of a time in ns since the epoch (seconds past `i32::MAX` are held there).
    pub fn set_stamp_ns(&mut self, time_ns: u64) {
        self.stamp_sec = i32::try_from(time_ns / 1_000_000_000).unwrap_or(i32::MAX);
        self.stamp_nanosec = (time_ns % 1_000_000_000) as u32;
    }

    /// The stamp in ns (0 before the epoch).
    pub fn stamp_ns(&self) -> u64 {
        u64::try_from(self.stamp_sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.stamp_nanosec)
    }

    /// The joint state of a frame's rows: two joints per rod whose row has a value (status
    /// `ok`, `predicted` or `conflict`), `rod<k>_slide` (m, m/s) and `rod<k>_turn` (rad, rad/s,
    /// whole turns counted), stamped `time_ns` (ns since the epoch).
    pub fn of_rows<'a>(
        rows: impl IntoIterator<Item = &'a Measurement>,
        time_ns: u64,
        frame_id: String,
    ) -> JointState {
        let mut m = JointState {
            frame_id,
            ..JointState::default()
        };
        m.set_stamp_ns(time_ns);
        for r in rows.into_iter().map(|r| r.sanitized()) {
            if !matches!(r.status, Status::Ok | Status::Predicted | Status::Conflict) {
                continue;
            }
            m.name.push(format!("rod{}_slide", r.rod));
            m.position.push(r.position_mm * 1e-3);
            m.velocity.push(r.velocity_mm_s * 1e-3);
            m.name.push(format!("rod{}_turn", r.rod));
            m.position.push(r.angle_unwrapped_rad);
            m.velocity.push(r.angular_velocity_rad_s);
        }
        m
    }

    /// [`JointState::of_rows`] in CDR, written straight into `out` (cleared first): the
    /// same bytes, with no allocation once `out` has grown to a message's size (a publisher's
    /// per-frame path).
    pub fn rows_to_cdr<'a>(
        rows: impl Iterator<Item = &'a Measurement> + Clone,
        time_ns: u64,
        frame_id: &str,
        out: &mut Vec<u8>,
    ) {
        // As `of_rows`: the rows made finite first (a NaN turns an `ok` row into one without a
        // value), then those with a value.
        let valued = rows
            .map(|r| r.sanitized())
            .filter(|r| matches!(r.status, Status::Ok | Status::Predicted | Status::Conflict));
        let mut w = CdrWriter::stamped(out, time_ns, frame_id);
        let n = valued.clone().count();
        w.u32(2 * n as u32);
        for r in valued.clone() {
            for suffix in ["_slide", "_turn"] {
                w.joint_name(r.rod, suffix);
            }
        }
        // Positions, then velocities (m and m/s for a slide, rad and rad/s for a turn), as
        // `of_rows` orders them; no effort.
        for velocity in [false, true] {
            w.u32(2 * n as u32);
            if n > 0 {
                w.align(8);
            }
            for r in valued.clone() {
                let (slide, turn) = if velocity {
                    (r.velocity_mm_s * 1e-3, r.angular_velocity_rad_s)
                } else {
                    (r.position_mm * 1e-3, r.angle_unwrapped_rad)
                };
                w.out.extend_from_slice(&slide.to_le_bytes());
                w.out.extend_from_slice(&turn.to_le_bytes());
            }
        }
        w.u32(0);
    }

    /// The message in CDR, appended to `out` (cleared first).
    pub fn to_cdr(&self, out: &mut Vec<u8>) {
        out.clear();
        out.extend_from_slice(&CDR_LE_HEADER);
        let mut w = CdrWriter { out };
        w.u32(self.stamp_sec as u32);
        w.u32(self.stamp_nanosec);
        w.string(&self.frame_id);
        w.u32(self.name.len() as u32);
        for n in &self.name {
            w.string(n);
        }
        for seq in [&self.position, &self.velocity, &self.effort] {
            w.f64s(seq);
        }
    }

    /// Parses a joint state in CDR (either byte order); never allocates more than the
    /// message's size.
    pub fn from_cdr(data: &[u8]) -> Result<JointState, CdrError> {
        let mut r = CdrReader::of(data)?;
        let stamp_sec = r.u32()? as i32;
        let stamp_nanosec = r.u32()?;
        let frame_id = r.string()?;
        let n = r.count(4)?;
        let mut name = Vec::with_capacity(n);
        for _ in 0..n {
            name.push(r.string()?);
        }
        let position = r.f64s()?;
        let velocity = r.f64s()?;
        let effort = r.f64s()?;
        Ok(JointState {
            stamp_sec,
            stamp_nanosec,
            frame_id,
            name,
            position,
            velocity,
            effort,
        })
    }
}

/// A `geometry_msgs/msg/PointStamped` or `geometry_msgs/msg/Vector3Stamped`: a header and
/// three `float64` (`point.x, y, z` or `vector.x, y, z`). The two messages have the same CDR
/// layout.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StampedXyz {
    /// `header.stamp.sec`, s.
    pub stamp_sec: i32,
    /// `header.stamp.nanosec`, ns.
    pub stamp_nanosec: u32,
    /// `header.frame_id`.
    pub frame_id: String,
    /// `x, y, z`.
    pub xyz: [f64; 3],
}

impl StampedXyz {
    /// The message in CDR, written into `out` (cleared first; no allocation once `out` has
    /// grown to a message's size).
    pub fn write_cdr(time_ns: u64, frame_id: &str, xyz: [f64; 3], out: &mut Vec<u8>) {
        let mut w = CdrWriter::stamped(out, time_ns, frame_id);
        w.align(8);
        for v in xyz {
            w.out.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// Parses the message in CDR (either byte order).
    pub fn from_cdr(data: &[u8]) -> Result<StampedXyz, CdrError> {
        let mut r = CdrReader::of(data)?;
        let stamp_sec = r.u32()? as i32;
        let stamp_nanosec = r.u32()?;
        let frame_id = r.string()?;
        let mut xyz = [0.0; 3];
        for v in &mut xyz {
            *v = r.f64()?;
        }
        Ok(StampedXyz {
            stamp_sec,
            stamp_nanosec,
            frame_id,
            xyz,
        })
    }
}

/// Why CDR bytes are not a joint state.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The bytes end before the field at this offset (after the header).
    #[error("the CDR message ends early (field at byte {0})")]
    Short(usize),
    /// Not a plain CDR encapsulation (its first two bytes).
    #[error("not a plain CDR message (encapsulation {0:02x?})")]
    Encapsulation([u8; 2]),
    /// A string that is not NUL-terminated UTF-8, at this offset.
    #[error("a CDR string at byte {0} is not valid")]
    BadString(usize),
}

/// Appends CDR fields after the 4-byte header (alignment counts from there).
struct CdrWriter<'a> {
    out: &'a mut Vec<u8>,
}

impl<'a> CdrWriter<'a> {
    /// A writer into `out` (cleared first) past the encapsulation header and a
    /// `std_msgs/Header` stamped `time_ns` with `frame_id`.
    fn stamped(out: &'a mut Vec<u8>, time_ns: u64, frame_id: &str) -> CdrWriter<'a> {
        let mut stamp = JointState::default();
        stamp.set_stamp_ns(time_ns);
        out.clear();
        out.extend_from_slice(&CDR_LE_HEADER);
        let mut w = CdrWriter { out };
        w.u32(stamp.stamp_sec as u32);
        w.u32(stamp.stamp_nanosec);
        w.string(frame_id);
        w
    }
    fn align(&mut self, n: usize) {
        let at = self.out.len() - CDR_LE_HEADER.len();
        let pad = (n - at % n) % n;
        self.out.resize(self.out.len() + pad, 0);
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.out.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.out.extend_from_slice(s.as_bytes());
        self.out.push(0);
    }
    /// The string `rod<rod><suffix>`, formatted in place.
    fn joint_name(&mut self, rod: u32, suffix: &str) {
        let mut digits = [0u8; 10];
        let (mut k, mut i) = (rod, digits.len());
        loop {
            i -= 1;
            digits[i] = b'0' + (k % 10) as u8;
            k /= 10;
            if k == 0 {
                break;
            }
        }
        let len = 3 + (digits.len() - i) + suffix.len();
        self.u32(len as u32 + 1);
        self.out.extend_from_slice(b"rod");
        self.out.extend_from_slice(&digits[i..]);
        self.out.extend_from_slice(suffix.as_bytes());
        self.out.push(0);
    }
    fn f64s(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        if !v.is_empty() {
            self.align(8);
        }
        for x in v {
            self.out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// Reads CDR fields of a body (the bytes after the header).
struct CdrReader<'a> {
    b: &'a [u8],
    at: usize,
    little: bool,
}

impl<'a> CdrReader<'a> {
    /// A reader of the body after `data`'s encapsulation header.
    fn of(data: &'a [u8]) -> Result<CdrReader<'a>, CdrError> {
        let (header, body) = data.split_at_checked(4).ok_or(CdrError::Short(0))?;
        let little = match header {
            [0, 1, _, _] => true,
            [0, 0, _, _] => false,
            _ => return Err(CdrError::Encapsulation([header[0], header[1]])),
        };
        Ok(CdrReader {
            b: body,
            at: 0,
            little,
        })
    }
    fn align(&mut self, n: usize) {
        self.at = self.at.div_ceil(n).saturating_mul(n);
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], CdrError> {
        let at = self.at;
        let s = at
            .checked_add(n)
            .and_then(|end| self.b.get(at..end))
            .ok_or(CdrError::Short(at))?;
        self.at = at + n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, CdrError> {
        self.align(4);
        let at = self.at;
        let b: [u8; 4] = self.take(4)?.try_into().map_err(|_| CdrError::Short(at))?;
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }
    /// A sequence's count, checked against the bytes left at `min_size` bytes an element.
    fn count(&mut self, min_size: usize) -> Result<usize, CdrError> {
        self.align(4);
        let at = self.at;
        let n = self.u32()? as usize;
        if n.saturating_mul(min_size) > self.b.len().saturating_sub(self.at) {
            return Err(CdrError::Short(at));
        }
        Ok(n)
    }
    fn string(&mut self) -> Result<String, CdrError> {
        let at = self.at;
        let n = self.u32()? as usize;
        let s = self.take(n)?;
        match s.split_last() {
            Some((0, text)) => {
                String::from_utf8(text.to_vec()).map_err(|_| CdrError::BadString(at))
            }
            _ => Err(CdrError::BadString(at)),
        }
    }
    fn f64(&mut self) -> Result<f64, CdrError> {
        self.align(8);
        let at = self.at;
        let b: [u8; 8] = self.take(8)?.try_into().map_err(|_| CdrError::Short(at))?;
        Ok(if self.little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }
    fn f64s(&mut self) -> Result<Vec<f64>, CdrError> {
        let n = self.count(8)?;
        if n > 0 {
            self.align(8);
        }
        let b = self.take(n.saturating_mul(8))?;
        Ok(b.chunks_exact(8)
            .map(|c| {
                let a = [c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]];
                if self.little {
                    f64::from_le_bytes(a)
                } else {
                    f64::from_be_bytes(a)
                }
            })
            .collect())
    }
}

/// A token of a ROS 2 topic name: letters, digits and `_` (anything else becomes `_`), not
/// starting with a digit (then `_` is put before it), never empty.
pub fn ros_name_token(s: &str) -> String {
    let mut t: String = s
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if t.is_empty() || t.starts_with(|c: char| c.is_ascii_digit()) {
        t.insert(0, '_');
    }
    t
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn rows_written_straight_to_cdr_are_the_joint_states_bytes() {
        use rodtrack_core::{CameraId, Timestamp};
        let row = |rod: u32, status: Status, position_mm: f64| Measurement {
            position_mm,
            velocity_mm_s: -3.5 * position_mm,
            angle_unwrapped_rad: 0.25 * rod as f64 - 7.0,
            angular_velocity_rad_s: 40.0,
            ..Measurement::empty(5, Timestamp(3_000_000_123), CameraId::Fused, rod, status)
        };
        for rows in [
            vec![],
            vec![row(3, Status::Occluded, 1.0)],
            vec![
                row(0, Status::Ok, 12.5),
                row(7, Status::Occluded, 3.0),
                row(12, Status::Predicted, -170.25),
                row(1234567, Status::Conflict, f64::NAN),
                row(4, Status::Ok, f64::INFINITY),
            ],
        ] {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            JointState::of_rows(&rows, 3_000_000_123, "rodtrack/t".into()).to_cdr(&mut a);
            JointState::rows_to_cdr(rows.iter(), 3_000_000_123, "rodtrack/t", &mut b);
            assert_eq!(a, b, "{} rows", rows.len());
            assert!(JointState::from_cdr(&b).is_ok());
            // Written again into the grown buffer: no allocation.
            let at = b.as_ptr();
            JointState::rows_to_cdr(rows.iter(), 3_000_000_123, "rodtrack/t", &mut b);
            assert_eq!((at, &a), (b.as_ptr(), &b));
        }
    }

    #[test]
    fn only_a_ball_with_a_finite_place_goes_out() {
        use rodtrack_core::{CameraId, Timestamp};
        let row = |status, x_mm: f64| BallRow {
            x_mm,
            y_mm: -250.0,
            vx_mm_s: 1500.0,
            vy_mm_s: -20.0,
            quality: 1.0,
            status,
            ..BallRow::lost(3, Timestamp(15_000_000), CameraId::Fused)
        };
        let (p, v) = ball_place_and_velocity(&row(BallStatus::Ok, 120.0), 0.0175).unwrap();
        assert_eq!(p, [0.12, -0.25, 0.0175]);
        assert_eq!(v, [1.5, -0.02, 0.0]);
        assert!(ball_place_and_velocity(&row(BallStatus::Predicted, 120.0), 0.0175).is_some());
        for (status, x) in [
            (BallStatus::Lost, 0.0),
            (BallStatus::Conflict, 120.0),
            (BallStatus::Ok, f64::NAN),
            (BallStatus::Predicted, f64::INFINITY),
        ] {
            assert!(
                ball_place_and_velocity(&row(status, x), 0.0175).is_none(),
                "{status:?} {x}"
            );
        }
    }

    #[test]
    fn the_message_definitions_are_rosbag2s_text() {
        let sep = "=".repeat(80);
        let header = format!(
            "\n{sep}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\n{sep}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
        );
        assert_eq!(
            JOINT_STATE_MSGDEF,
            format!("std_msgs/Header header\n\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n{header}")
        );
        for (def, ty, field) in [
            (POINT_STAMPED_MSGDEF, "Point", "point"),
            (VECTOR3_STAMPED_MSGDEF, "Vector3", "vector"),
        ] {
            assert_eq!(
                def,
                format!("std_msgs/Header header\ngeometry_msgs/{ty} {field}\n{header}\n{sep}\nMSG: geometry_msgs/{ty}\nfloat64 x\nfloat64 y\nfloat64 z\n")
            );
        }
    }

    #[test]
    fn a_stamped_vector_has_the_cdr_layout_byte_for_byte() {
        let mut b = Vec::new();
        StampedXyz::write_cdr(3_000_000_007, "ab", [1.5, -2.0, 0.25], &mut b);
        let mut want = vec![0, 1, 0, 0];
        want.extend_from_slice(&3u32.to_le_bytes()); // sec
        want.extend_from_slice(&7u32.to_le_bytes()); // nanosec
        want.extend_from_slice(&[3, 0, 0, 0, b'a', b'b', 0]); // frame_id "ab\0", ends at 15
        want.push(0); // pad to 16 (8-aligned)
        for v in [1.5f64, -2.0, 0.25] {
            want.extend_from_slice(&v.to_le_bytes());
        }
        assert_eq!(b, want);
        let m = StampedXyz::from_cdr(&b).unwrap();
        assert_eq!(
            (m.stamp_sec, m.stamp_nanosec, m.frame_id.as_str()),
            (3, 7, "ab")
        );
        assert_eq!(m.xyz, [1.5, -2.0, 0.25]);
        // Padding to the point's 8-byte alignment: 7 bytes after "abcd\0", none after an
        // 11-letter id; a message cut short is an error, not a panic.
        StampedXyz::write_cdr(0, "abcd", [0.0; 3], &mut b);
        assert_eq!(b.len(), 4 + 8 + 4 + 5 + 7 + 24);
        StampedXyz::write_cdr(0, "abcdefghijk", [0.0; 3], &mut b);
        assert_eq!(b.len(), 4 + 8 + 4 + 12 + 24);
        let at = b.as_ptr();
        StampedXyz::write_cdr(0, "abcdefghijk", [1.0; 3], &mut b);
        assert_eq!(at, b.as_ptr(), "written again without allocating");
        for n in 0..b.len() {
            assert!(StampedXyz::from_cdr(&b[..n]).is_err(), "{n} bytes");
        }
    }

    #[test]
    fn a_joint_state_has_the_cdr_layout_byte_for_byte() {
        let mut m = JointState {
            frame_id: "ab".into(),
            name: vec!["j".into()],
            position: vec![1.5],
            velocity: vec![],
            effort: vec![],
            ..JointState::default()
        };
        m.set_stamp_ns(3_000_000_007);
        let mut b = Vec::new();
        m.to_cdr(&mut b);
        let mut want = vec![0, 1, 0, 0];
        want.extend_from_slice(&3u32.to_le_bytes()); // sec
        want.extend_from_slice(&7u32.to_le_bytes()); // nanosec
        want.extend_from_slice(&[3, 0, 0, 0, b'a', b'b', 0]); // frame_id "ab\0"
        want.push(0); // pad to 4 (offset 15 -> 16)
        want.extend_from_slice(&[1, 0, 0, 0]); // 1 name
        want.extend_from_slice(&[2, 0, 0, 0, b'j', 0]); // "j\0", ends at 26
        want.extend_from_slice(&[0, 0]); // pad to 28
        want.extend_from_slice(&[1, 0, 0, 0]); // 1 position, ends at 32 (8-aligned)
        want.extend_from_slice(&1.5f64.to_le_bytes());
        want.extend_from_slice(&[0; 4]); // no velocity: no padding after the count
        want.extend_from_slice(&[0; 4]); // no effort
        assert_eq!(b, want);
        assert_eq!(JointState::from_cdr(&b).unwrap(), m);
        assert_eq!(m.stamp_ns(), 3_000_000_007);
    }

    #[test]
    fn bad_cdr_is_an_error() {
        let mut b = Vec::new();
        JointState::default().to_cdr(&mut b);
        assert!(JointState::from_cdr(&b).is_ok());
        for n in 0..b.len() {
            assert!(JointState::from_cdr(&b[..n]).is_err(), "cut at {n}");
        }
        // A sequence count far past the message's end allocates nothing.
        let mut big = b.clone();
        // (The names' count: after the stamp, 8 bytes, and the frame id, 4 + 1 padded to 8.)
        big[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(JointState::from_cdr(&big), Err(CdrError::Short(16)));
        assert!(matches!(
            JointState::from_cdr(&[0, 7, 0, 0]),
            Err(CdrError::Encapsulation(_))
        ));
    }

    #[test]
    fn topic_tokens_are_ros_names() {
        assert_eq!(ros_name_token("cam0"), "cam0");
        assert_eq!(ros_name_token("0"), "_0");
        assert_eq!(ros_name_token("left cam-1"), "left_cam_1");
        assert_eq!(ros_name_token(""), "_");
    }
}
