//! MCAP recordings: what the recorder writes, read back by this crate's reader (the `mcap`
//! crate reads them in the binary's tests); chunking, a file cut short, and errors that name
//! the file.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::{CameraId, Measurement, Status, Timestamp};
use rodtrack_io::mcap::{
    parse_mcap, parse_rows_message, read_mcap, ChunkLimits, Compression, JointState, McapRecorder,
    Profile, RecordOptions, JOINT_STATE_MSGDEF, MAX_CHUNK_BYTES, ROWS_SCHEMA_NAME,
};
use rodtrack_io::{IoError, MeasurementSink};
use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rodtrack-mcap-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn row(frame: u64, camera: CameraId, rod: u32) -> Measurement {
    Measurement {
        frame,
        timestamp_ns: Timestamp(5_000_000 * frame + 17),
        camera,
        rod,
        position_mm: 1.0 / 3.0 + f64::from(rod),
        angle_rad: 0.25 * f64::from(rod),
        angle_unwrapped_rad: -7.5 + frame as f64,
        velocity_mm_s: 12.5,
        angular_velocity_rad_s: -3.0,
        quality: 0.9,
        status: if rod == 2 { Status::Lost } else { Status::Ok },
        turns_known: rod != 1,
    }
}

/// One frame set: two cameras and the fused rows, three rods each.
fn set(frame: u64) -> Vec<Measurement> {
    let mut v = Vec::new();
    for cam in [CameraId::Camera(0), CameraId::Camera(1), CameraId::Fused] {
        for rod in 0..3 {
            v.push(row(frame, cam, rod));
        }
    }
    v
}

fn options(span_ns: u64) -> RecordOptions {
    RecordOptions {
        table: "t1".into(),
        cameras: vec![(0, "left".into()), (1, "right".into())],
        chunk: ChunkLimits {
            span_ns,
            bytes: 1 << 20,
        },
        frames_per_s: 0.0,
        ..RecordOptions::default()
    }
}

#[test]
fn rows_come_back_exactly_per_camera_and_frame() {
    let path = tmp("rows.mcap");
    let rec = McapRecorder::create(&path, options(20_000_000)).unwrap();
    let mut sink = rec.sink();
    let frames = 0..25u64;
    for f in frames.clone() {
        sink.write(&set(f)).unwrap();
    }
    sink.flush().unwrap();
    let summary = rec.finish().unwrap();
    // Rows and joints per camera and fused: 6 channels, 2 schemas, 6 messages per frame.
    assert_eq!((summary.channels, summary.schemas), (6, 2));
    assert_eq!(summary.messages, 6 * 25);
    // 20 ms chunks of 5 ms frames: several chunks.
    assert!(summary.chunks >= 5, "{summary:?}");
    let file = read_mcap(&path).unwrap();
    assert!(file.complete && file.cut.is_none());
    assert!(file.library.starts_with("rodtrack "));
    let topics: Vec<&str> = file.channels.values().map(|c| c.topic.as_str()).collect();
    for t in [
        "/rodtrack/t1/cam/left/rows",
        "/rodtrack/t1/cam/right/rows",
        "/rodtrack/t1/fused/rows",
        "/rodtrack/t1/cam/left/joints",
        "/rodtrack/t1/fused/joints",
    ] {
        assert!(topics.contains(&t), "{t} not in {topics:?}");
    }
    let mut back = Vec::new();
    for m in &file.messages {
        let ch = &file.channels[&m.channel];
        let schema = &file.schemas[&ch.schema_id];
        assert_eq!(
            (ch.message_encoding.as_str(), schema.encoding.as_str()),
            ("json", "jsonschema")
        );
        if schema.name != ROWS_SCHEMA_NAME {
            continue;
        }
        let msg = parse_rows_message(&m.data).unwrap();
        assert_eq!(m.log_time_ns, msg.rows[0].timestamp_ns.as_nanos());
        back.extend(msg.rows);
    }
    let all: Vec<Measurement> = frames.flat_map(set).collect();
    assert_eq!(back, all);
    // The joints of frame 3, fused: rods 0 and 1 (rod 2 is lost), slide in m.
    let joints = file.channel("/rodtrack/t1/fused/joints").unwrap().id;
    let m = file
        .messages
        .iter()
        .filter(|m| m.channel == joints)
        .nth(3)
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
    assert_eq!(
        v["name"],
        serde_json::json!(["rod0_slide", "rod0_turn", "rod1_slide", "rod1_turn"])
    );
    assert!((v["position"][2].as_f64().unwrap() - (4.0 / 3.0) * 1e-3).abs() < 1e-15);
    assert_eq!(v["position"][1].as_f64().unwrap(), -4.5);
    assert_eq!(v["header"]["stamp"]["nanosec"], 15_000_017);
}

/// The offsets of the top-level chunk records.
fn chunk_offsets(b: &[u8]) -> Vec<usize> {
    let mut at = 8;
    let mut out = Vec::new();
    while at + 9 <= b.len() {
        let len = u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        if b[at] == 0x06 {
            out.push(at);
        }
        if b[at] == 0x0F {
            break;
        }
        at += 9 + len;
    }
    out
}

#[test]
fn a_file_cut_short_gives_its_complete_chunks() {
    let path = tmp("cut.mcap");
    let rec = McapRecorder::create(&path, options(u64::MAX)).unwrap();
    let mut sink = rec.sink();
    for f in 0..10 {
        sink.write(&set(f)).unwrap();
        if f == 4 {
            // A flush closes the chunk: frames 0..=4 are on disk from here.
            sink.flush().unwrap();
        }
    }
    rec.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    // Cut in the middle of the second chunk, as a crash would leave it.
    let first = parse_mcap(&bytes, "x.mcap".as_ref()).unwrap();
    assert_eq!(first.messages.len(), 60);
    let cut_at = chunk_offsets(&bytes)[1] + 50;
    let file = parse_mcap(&bytes[..cut_at], "x.mcap".as_ref()).unwrap();
    assert!(!file.complete);
    assert!(
        file.cut.as_deref().unwrap().contains("cut short"),
        "{:?}",
        file.cut
    );
    assert_eq!(file.messages.len(), 30, "frames 0 to 4, 6 messages each");
}

#[test]
fn errors_name_the_file() {
    let missing = tmp("no-such-folder").join("x.mcap");
    let e = McapRecorder::create(&missing, options(1)).err().unwrap();
    assert!(
        matches!(e, IoError::File { .. }) && e.to_string().contains("x.mcap"),
        "{e}"
    );
    let e = parse_mcap(b"not an mcap file", "y.mcap".as_ref()).unwrap_err();
    assert!(
        e.to_string().contains("y.mcap") && e.to_string().contains("magic"),
        "{e}"
    );
    let e = read_mcap(&missing).unwrap_err();
    assert!(e.to_string().contains("x.mcap"), "{e}");
    // A damaged chunk is refused, not read as garbage.
    let path = tmp("damaged.mcap");
    let rec = McapRecorder::create(&path, options(u64::MAX)).unwrap();
    rec.sink().write(&set(0)).unwrap();
    rec.finish().unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    // In the chunk (the schema has the name too, followed by a space).
    let at = bytes
        .windows(15)
        .position(|w| w == b"\"position_mm\":0")
        .unwrap();
    bytes[at + 1] = b'P';
    let r = parse_mcap(&bytes, "z.mcap".as_ref());
    let Err(e) = r else {
        panic!("a damaged chunk must be an error");
    };
    assert!(e.to_string().contains("damaged"), "{e}");
    // Rows after the end are refused with the file's name.
    let e = rec.sink().write(&set(1)).unwrap_err();
    assert!(e.to_string().contains("damaged.mcap"), "{e}");
}

#[test]
fn frames_are_recorded_at_the_rate_asked() {
    let path = tmp("frames.mcap");
    let mut o = options(u64::MAX);
    o.frames_per_s = 50.0;
    let rec = McapRecorder::create(&path, o).unwrap();
    let mut kept = 0;
    for k in 0..100u64 {
        // 200 fps: every 4th frame at 50 per second.
        let t = 5_000_000 * k;
        if rec.wants_frame(0, t) {
            rec.record_frame(0, t, 4, 2, &[0, 1, 2, 3, 250, 251, 252, 253])
                .unwrap();
            kept += 1;
        }
    }
    assert_eq!(kept, 25);
    assert!(rec.record_frame(0, 0, 4, 4, &[0; 8]).is_err());
    rec.finish().unwrap();
    let file = read_mcap(&path).unwrap();
    let ch = file.channel("/rodtrack/t1/cam/left/image").unwrap();
    assert_eq!(file.schemas[&ch.schema_id].name, "foxglove.RawImage");
    let v: serde_json::Value = serde_json::from_slice(&file.messages[1].data).unwrap();
    assert_eq!(v["timestamp"]["nsec"], 20_000_000);
    assert_eq!(
        (v["width"].as_u64(), v["encoding"].as_str()),
        (Some(4), Some("mono8"))
    );
    assert_eq!(v["data"], "AAECA/r7/P0=");
}

/// Records frames 0..`frames` of [`set`] with `o`; the file's bytes.
fn record(name: &str, o: RecordOptions, frames: u64) -> Vec<u8> {
    let path = tmp(name);
    let rec = McapRecorder::create(&path, o).unwrap();
    let mut sink = rec.sink();
    for f in 0..frames {
        sink.write(&set(f)).unwrap();
    }
    rec.finish().unwrap();
    std::fs::read(&path).unwrap()
}

#[test]
fn lz4_chunks_hold_the_same_messages_in_fewer_bytes() {
    let plain = record("plain.mcap", options(20_000_000), 40);
    let mut o = options(20_000_000);
    o.compression = Compression::Lz4;
    let packed = record("lz4.mcap", o, 40);
    let (a, b) = (
        parse_mcap(&plain, "a.mcap".as_ref()).unwrap(),
        parse_mcap(&packed, "b.mcap".as_ref()).unwrap(),
    );
    assert!(b.complete);
    assert_eq!(a.messages, b.messages);
    assert_eq!(a.messages.len(), 6 * 40);
    assert!(
        packed.len() * 2 < plain.len(),
        "{} bytes in lz4 chunks, {} plain",
        packed.len(),
        plain.len()
    );
    // Every chunk record says lz4 (the compression string follows 28 bytes of fields).
    let offsets = chunk_offsets(&packed);
    assert!(offsets.len() >= 5);
    for at in offsets {
        assert_eq!(&packed[at + 9 + 28..at + 9 + 35], b"\x03\0\0\0lz4");
    }
}

#[test]
fn compressed_chunks_that_lie_are_refused() {
    let mut o = options(u64::MAX);
    o.compression = Compression::Lz4;
    let good = record("lie.mcap", o, 3);
    let at = chunk_offsets(&good)[0] + 9;
    // The uncompressed size: past the cap, then one byte more than the frame holds.
    for (size, want) in [(MAX_CHUNK_BYTES + 1, "claims"), (1, "damaged")] {
        let mut b = good.clone();
        b[at + 16..at + 24].copy_from_slice(&size.to_le_bytes());
        let e = parse_mcap(&b, "l.mcap".as_ref()).unwrap_err();
        assert!(e.to_string().contains(want), "{e}");
    }
    // zstd is named, not misread.
    let mut b = good.clone();
    b[at + 32..at + 35].copy_from_slice(b"zst");
    let e = parse_mcap(&b, "z.mcap".as_ref()).unwrap_err();
    assert!(e.to_string().contains("\"zst\""), "{e}");
    // A damaged frame is an error.
    let mut b = good;
    let n = b.len();
    b[at + 60..n - 200].iter_mut().for_each(|x| *x ^= 0x5A);
    assert!(parse_mcap(&b, "d.mcap".as_ref()).is_err());
}

#[test]
fn a_ros2_bag_holds_joint_states_in_cdr_with_their_schema_and_qos() {
    let mut o = options(20_000_000);
    o.profile = Profile::Ros2;
    o.compression = Compression::Lz4;
    o.cameras[1].1 = "2nd cam".into();
    let bytes = record("ros2.mcap", o, 10);
    let file = parse_mcap(&bytes, "r.mcap".as_ref()).unwrap();
    assert_eq!(file.profile, "ros2");
    let topics: Vec<&str> = file.channels.values().map(|c| c.topic.as_str()).collect();
    assert_eq!(
        topics,
        [
            "/rodtrack/t1/cam/left/joint_states",
            "/rodtrack/t1/cam/_2nd_cam/joint_states",
            "/rodtrack/t1/fused/joint_states",
        ]
    );
    assert_eq!(file.schemas.len(), 1);
    let schema = &file.schemas[&1];
    assert_eq!(
        (schema.name.as_str(), schema.encoding.as_str()),
        ("sensor_msgs/msg/JointState", "ros2msg")
    );
    assert_eq!(schema.data, JOINT_STATE_MSGDEF.as_bytes());
    for c in file.channels.values() {
        assert_eq!(c.message_encoding, "cdr");
        assert!(c.metadata["offered_qos_profiles"].contains("reliability: 1"));
    }
    assert_eq!(file.messages.len(), 3 * 10);
    let fused = file.channel("/rodtrack/t1/fused/joint_states").unwrap().id;
    let m = file
        .messages
        .iter()
        .filter(|m| m.channel == fused)
        .nth(3)
        .unwrap();
    assert_eq!(&m.data[..4], &[0, 1, 0, 0]);
    let js = JointState::from_cdr(&m.data).unwrap();
    assert_eq!(js.stamp_ns(), 15_000_017);
    assert_eq!(m.log_time_ns, 15_000_017);
    assert_eq!(js.frame_id, "rodtrack/t1/fused");
    assert_eq!(
        js.name,
        ["rod0_slide", "rod0_turn", "rod1_slide", "rod1_turn"]
    );
    // Rod 1: (1/3 + 1) mm, -7.5 + 3 rad; 12.5 mm/s, -3 rad/s; rod 2 (lost) left out.
    assert_eq!(js.position[2], (1.0 / 3.0 + 1.0) * 1e-3);
    assert_eq!(js.position[3], -4.5);
    assert_eq!(js.velocity, [0.0125, -3.0, 0.0125, -3.0]);
    assert!(js.effort.is_empty());
}
