//! The ball in recordings: `track --ball-out --mcap` read back with the `mcap` crate, every
//! row of the ball's CSV a `rodtrack.Ball` message on its camera's (or the fused) channel.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{track_two_cameras, two_cameras_of};
use rodtrack_io::mcap::{parse_ball_message, BALL_SCHEMA_NAME};
use std::collections::BTreeMap;

#[test]
fn a_recording_holds_every_ball_row_of_the_csv() {
    let (dir, calib) = two_cameras_of("mcap_ball", "ball", 40);
    let (csv, ball, mcap) = (dir.join("r.csv"), dir.join("b.csv"), dir.join("r.mcap"));
    let o = track_two_cameras(
        &dir,
        &calib,
        &[
            "--out",
            csv.to_str().unwrap(),
            "--ball-out",
            ball.to_str().unwrap(),
            "--mcap",
            mcap.to_str().unwrap(),
            "--table",
            "t1",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // The CSV's rows by (camera, frame): the line as written.
    let text = std::fs::read_to_string(&ball).unwrap();
    let want: BTreeMap<(String, u64), String> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            ((f[2].to_string(), f[0].parse().unwrap()), l.to_string())
        })
        .collect();
    assert_eq!(want.len(), 3 * 40, "2 cameras and fused per frame");
    assert!(want.values().filter(|l| l.ends_with(",ok")).count() > 60);

    let bytes = std::fs::read(&mcap).unwrap();
    let mut got = BTreeMap::new();
    let mut sequences: BTreeMap<String, Vec<u32>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if !m.channel.topic.ends_with("/ball") {
            continue;
        }
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(
            (schema.name.as_str(), schema.encoding.as_str()),
            (BALL_SCHEMA_NAME, "jsonschema")
        );
        assert_eq!(m.channel.message_encoding, "json");
        assert_eq!(m.channel.metadata["table"], "t1");
        let b = parse_ball_message(&m.data).unwrap();
        assert_eq!(m.log_time, b.row.timestamp_ns.as_nanos());
        let (camera, topic) = match b.row.camera {
            rodtrack_core::CameraId::Fused => ("fused".to_string(), "/rodtrack/t1/fused/ball"),
            rodtrack_core::CameraId::Camera(k) => (k.to_string(), ""),
        };
        if topic.is_empty() {
            assert_eq!(
                m.channel.topic,
                format!("/rodtrack/t1/cam/cam{camera}/ball")
            );
            assert!(b.sigma_mm > 0.0, "a camera's row carries its spread: {b:?}");
        } else {
            assert_eq!(m.channel.topic, topic);
            assert!(b.sigma_mm.is_nan(), "a fused row has no spread: {b:?}");
        }
        assert_eq!(m.channel.metadata["camera"], b.camera_name);
        sequences
            .entry(m.channel.topic.clone())
            .or_default()
            .push(m.sequence);
        // The row as the CSV writes it: the same line.
        assert!(
            got.insert((camera, b.row.frame), b.row.csv_line())
                .is_none(),
            "one message per row"
        );
    }
    assert_eq!(got, want, "the recording's ball rows are the CSV's");
    assert_eq!(sequences.len(), 3);
    for (topic, s) in sequences {
        assert_eq!(s, (0..40).collect::<Vec<u32>>(), "{topic}");
    }
}
