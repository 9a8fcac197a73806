//! `track --mcap`: the recording read back with the `mcap` crate (the reader of the format's
//! authors, on which Foxglove's and Rerun's loaders stand) and checked row by row against the
//! CSV file of the same run, with its channels, schemas, summary and indexes.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{rodtrack, two_cameras};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The suite's recording of two cameras (40 frames) and their calibration, made once.
fn fixture() -> &'static (PathBuf, PathBuf) {
    static F: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    F.get_or_init(|| two_cameras("mcap_recording", 40))
}

/// `track` of the fixture's recording (table `t1`) into `csv` and the MCAP file `mcap`, with
/// the MCAP options `extra`.
fn track_with_mcap(
    dir: &Path,
    calib: &Path,
    csv: &Path,
    mcap: &Path,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "--out",
        csv.to_str().unwrap(),
        "--mcap",
        mcap.to_str().unwrap(),
        "--table",
        "t1",
    ];
    args.extend_from_slice(extra);
    common::track_two_cameras(dir, calib, &args)
}

/// `v` with `d` decimals as the files write it (no minus sign on a zero).
fn fixed(v: f64, d: usize) -> String {
    let s = format!("{v:.d$}");
    if s.starts_with('-') && s[1..].bytes().all(|b| b == b'0' || b == b'.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// A rows message's rows as the CSV lines of the same rows.
fn csv_lines(msg: &serde_json::Value) -> Vec<String> {
    let ns = msg["timestamp_ns"].as_u64().unwrap();
    let camera = match msg.get("camera_index") {
        Some(k) => k.as_u64().unwrap().to_string(),
        None => "fused".to_string(),
    };
    let f = |r: &serde_json::Value, k: &str, d: usize| fixed(r[k].as_f64().unwrap(), d);
    msg["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            format!(
                "{},{}.{:09},{camera},{},{},{},{},{},{},{},{},{}",
                msg["frame"],
                ns / 1_000_000_000,
                ns % 1_000_000_000,
                r["rod"],
                f(r, "position_mm", 4),
                f(r, "angle_rad", 6),
                f(r, "angle_unwrapped_rad", 6),
                f(r, "velocity_mm_s", 3),
                f(r, "angular_velocity_rad_s", 4),
                f(r, "quality", 4),
                r["status"].as_str().unwrap(),
                r["turns_known"],
            )
        })
        .collect()
}

#[test]
fn the_recording_holds_every_row_of_the_csv_with_its_channels_and_indexes() {
    let (dir, calib) = fixture();
    let (csv, mcap) = (dir.join("rows.csv"), dir.join("rows.mcap"));
    let o = track_with_mcap(dir, calib, &csv, &mcap, &["--mcap-frames", "50"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("rows.mcap") && stdout.contains("messages"),
        "{stdout}"
    );
    let bytes = std::fs::read(&mcap).unwrap();

    // Every message, streamed.
    let messages: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    let mut by_topic: BTreeMap<String, Vec<&mcap::Message>> = BTreeMap::new();
    for m in &messages {
        by_topic.entry(m.channel.topic.clone()).or_default().push(m);
        assert_eq!(m.channel.message_encoding, "json");
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "jsonschema");
        let s: serde_json::Value = serde_json::from_slice(&schema.data).unwrap();
        assert_eq!(s["title"].as_str(), Some(schema.name.as_str()));
        assert_eq!(m.channel.metadata["table"], "t1");
        assert_eq!(m.log_time, m.publish_time);
    }
    let topics: BTreeSet<&str> = by_topic.keys().map(String::as_str).collect();
    let want: BTreeSet<&str> = [
        "/rodtrack/t1/cam/cam0/rows",
        "/rodtrack/t1/cam/cam1/rows",
        "/rodtrack/t1/fused/rows",
        "/rodtrack/t1/cam/cam0/joints",
        "/rodtrack/t1/cam/cam1/joints",
        "/rodtrack/t1/fused/joints",
        "/rodtrack/t1/cam/cam0/image",
        "/rodtrack/t1/cam/cam1/image",
    ]
    .into();
    assert_eq!(topics, want);

    // Rows: every CSV line once, nothing else; log time = the frame's capture timestamp.
    let mut from_mcap = Vec::new();
    let mut fused_rows: BTreeMap<u64, Vec<serde_json::Value>> = BTreeMap::new();
    for (topic, schema) in [
        ("/rodtrack/t1/cam/cam0/rows", "rodtrack.Rows"),
        ("/rodtrack/t1/cam/cam1/rows", "rodtrack.Rows"),
        ("/rodtrack/t1/fused/rows", "rodtrack.Rows"),
    ] {
        let mut last_frame = None;
        for m in &by_topic[topic] {
            assert_eq!(m.channel.schema.as_ref().unwrap().name, schema);
            let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
            assert_eq!(v["timestamp_ns"].as_u64(), Some(m.log_time));
            let frame = v["frame"].as_u64().unwrap();
            assert!(last_frame < Some(frame), "{topic}: frames in order");
            last_frame = Some(frame);
            if topic.contains("fused") {
                fused_rows.insert(m.log_time, v["rows"].as_array().unwrap().clone());
            }
            from_mcap.extend(csv_lines(&v));
        }
        assert_eq!(by_topic[topic].len(), 40, "{topic}: one message per frame");
    }
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut from_csv: Vec<String> = text.lines().skip(1).map(str::to_string).collect();
    from_csv.sort();
    from_mcap.sort();
    assert!(from_csv.len() > 200, "{} rows", from_csv.len());
    assert_eq!(from_mcap, from_csv);

    // Joints: the fused rows with a value, slide in m, turn in rad.
    let mut joints_seen = 0;
    for m in &by_topic["/rodtrack/t1/fused/joints"] {
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let stamp = &v["header"]["stamp"];
        let ns =
            stamp["sec"].as_u64().unwrap() * 1_000_000_000 + stamp["nanosec"].as_u64().unwrap();
        assert_eq!(ns, m.log_time);
        let rows = &fused_rows[&m.log_time];
        let mut want = Vec::new();
        for r in rows {
            if matches!(r["status"].as_str(), Some("ok" | "predicted" | "conflict")) {
                let k = r["rod"].as_u64().unwrap();
                let num = |key: &str| r[key].as_f64().unwrap();
                want.push((
                    format!("rod{k}_slide"),
                    num("position_mm") * 1e-3,
                    num("velocity_mm_s") * 1e-3,
                ));
                want.push((
                    format!("rod{k}_turn"),
                    num("angle_unwrapped_rad"),
                    num("angular_velocity_rad_s"),
                ));
            }
        }
        let got: Vec<(String, f64, f64)> = (0..v["name"].as_array().unwrap().len())
            .map(|k| {
                (
                    v["name"][k].as_str().unwrap().to_string(),
                    v["position"][k].as_f64().unwrap(),
                    v["velocity"][k].as_f64().unwrap(),
                )
            })
            .collect();
        // serde_json's default parser may miss the nearest f64 by one unit in the last place.
        let near = |a: f64, b: f64| (a - b).abs() <= 1e-15 * a.abs().max(b.abs());
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert!(
                g.0 == w.0 && near(g.1, w.1) && near(g.2, w.2),
                "{g:?} != {w:?}"
            );
        }
        joints_seen += got.len();
    }
    assert!(joints_seen > 100, "{joints_seen} joints");

    // Frames: 50 per second of a 200 fps run, downscaled grey.
    for cam in ["cam0", "cam1"] {
        let frames = &by_topic[&format!("/rodtrack/t1/cam/{cam}/image")];
        assert_eq!(
            frames.len(),
            10,
            "{cam}: 40 frames at 200 fps, 50 recorded per second"
        );
        let v: serde_json::Value = serde_json::from_slice(&frames[0].data).unwrap();
        let (w, h) = (v["width"].as_u64().unwrap(), v["height"].as_u64().unwrap());
        assert!(w.max(h) <= 480 && w > 0 && h > 0, "{w}x{h}");
        assert_eq!(v["encoding"], "mono8");
        assert_eq!(
            v["data"].as_str().unwrap().len() as u64,
            (w * h).div_ceil(3) * 4
        );
    }

    // The summary and the indexes, as indexed readers (Foxglove, Rerun) use them.
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    let stats = summary.stats.as_ref().unwrap();
    assert_eq!(stats.message_count, messages.len() as u64);
    assert_eq!(stats.channel_count as usize, summary.channels.len());
    assert_eq!(summary.channels.len(), want.len());
    assert_eq!(stats.chunk_count as usize, summary.chunk_indexes.len());
    assert!(!summary.chunk_indexes.is_empty());
    let mut indexed = 0;
    for ci in &summary.chunk_indexes {
        let in_chunk: Vec<mcap::Message> = summary
            .stream_chunk(&bytes, ci)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert!(in_chunk
            .iter()
            .all(|m| (ci.message_start_time..=ci.message_end_time).contains(&m.log_time)));
        for (channel, entries) in summary.read_message_indexes(&bytes, ci).unwrap() {
            for e in entries {
                let m = summary.seek_message(&bytes, ci, &e).unwrap();
                assert_eq!((m.log_time, m.channel.id), (e.log_time, channel.id));
                indexed += 1;
            }
        }
    }
    assert_eq!(indexed, messages.len());
}

#[test]
fn a_recording_alone_is_an_output_and_a_bad_path_is_named() {
    let (dir, calib) = fixture();
    let rec = dir.join("rec");
    let mcap = dir.join("only.mcap");
    let args = |out: &Path| {
        vec![
            "track".to_string(),
            "--calib".into(),
            calib.display().to_string(),
            "--input".into(),
            rec.join("cam0").display().to_string(),
            "--input".into(),
            rec.join("cam1").display().to_string(),
            "--mcap".into(),
            out.display().to_string(),
            "--max-frames".into(),
            "4".into(),
        ]
    };
    let a = args(&mcap);
    let o = rodtrack(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&mcap).unwrap();
    assert_eq!(mcap::MessageStream::new(&bytes).unwrap().count(), 4 * 6);
    let bad = dir.join("no-such-folder").join("x.mcap");
    let a = args(&bad);
    let o = rodtrack(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("x.mcap"), "{err}");
}

/// A joint: its name, position and velocity.
type Joint = (String, f64, f64);

#[test]
fn a_ros2_bag_in_lz4_chunks_holds_every_row_as_joint_states() {
    use rodtrack_io::mcap::JointState;
    let (dir, calib) = fixture();
    let (csv, bag) = (dir.join("ros2.csv"), dir.join("ros2.mcap"));
    let o = track_with_mcap(
        dir,
        calib,
        &csv,
        &bag,
        &["--mcap-ros2", "--mcap-compression", "lz4"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&bag).unwrap();
    // The header's profile (after the magic, the opcode and the length: a u32-long string).
    assert_eq!(&bytes[17..25], b"\x04\0\0\0ros2");

    // The CSV's rows with a value, as joints: (topic, ns) -> [(name, position, velocity)].
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut want: BTreeMap<(String, u64), Vec<Joint>> = BTreeMap::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let (s, ns) = f[1].split_once('.').unwrap();
        let t = s.parse::<u64>().unwrap() * 1_000_000_000 + ns.parse::<u64>().unwrap();
        let topic = match f[2] {
            "fused" => "/rodtrack/t1/fused/joint_states".to_string(),
            k => format!("/rodtrack/t1/cam/cam{k}/joint_states"),
        };
        let entry = want.entry((topic, t)).or_default();
        if !matches!(f[10], "ok" | "predicted" | "conflict") {
            continue;
        }
        let num = |k: usize| f[k].parse::<f64>().unwrap();
        entry.push((format!("rod{}_slide", f[3]), num(4) * 1e-3, num(7) * 1e-3));
        entry.push((format!("rod{}_turn", f[3]), num(6), num(8)));
    }
    assert_eq!(want.len(), 3 * 40);

    let mut seen = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.channel.message_encoding, "cdr");
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(
            (schema.name.as_str(), schema.encoding.as_str()),
            ("sensor_msgs/msg/JointState", "ros2msg")
        );
        assert!(m.channel.metadata.contains_key("offered_qos_profiles"));
        let js = JointState::from_cdr(&m.data).unwrap();
        assert_eq!(js.stamp_ns(), m.log_time);
        let w = &want[&(m.channel.topic.clone(), m.log_time)];
        assert_eq!(js.name.len(), w.len());
        assert!(js.effort.is_empty());
        for (k, (name, p, v)) in w.iter().enumerate() {
            // The CSV's decimals: 4 for mm, 6 for rad, 3 for mm/s, 4 for rad/s.
            let (dp, dv) = if name.ends_with("slide") {
                (0.5e-7, 0.5e-6)
            } else {
                (0.5e-6, 0.5e-4)
            };
            assert_eq!(&js.name[k], name);
            assert!((js.position[k] - p).abs() <= dp * 1.001, "{name}");
            assert!((js.velocity[k] - v).abs() <= dv * 1.001, "{name}");
        }
        seen += 1;
    }
    assert_eq!(seen, want.len());
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    assert!(!summary.chunk_indexes.is_empty());
    for ci in &summary.chunk_indexes {
        assert_eq!(ci.compression, "lz4");
        assert!(ci.compressed_size < ci.uncompressed_size);
    }

    // Frames have no place in the bag.
    let o = track_with_mcap(
        dir,
        calib,
        &csv,
        &bag,
        &["--mcap-ros2", "--mcap-frames", "5"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--mcap-ros2"), "{err}");
}
