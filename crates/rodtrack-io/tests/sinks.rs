//! Measurement sinks and readers.
#![allow(clippy::unwrap_used, missing_docs)]

use rodtrack_core::measurement::OUTPUT_COLUMNS;
use rodtrack_core::{CameraId, Measurement, Status};
use rodtrack_io::sink::{
    decode_udp_packet, encode_udp_packet, parse_measurements_csv, UDP_HEADER_BYTES, UDP_ROW_BYTES,
};
use rodtrack_io::Timestamp;
use rodtrack_io::{
    read_measurements_csv, read_measurements_jsonl, CsvSink, JsonlSink, MeasurementSink, UdpSink,
};
use std::io::Write;
use std::path::{Path, PathBuf};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rodtrack-io-sinks-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn row(frame: u64, camera: CameraId, rod: u32) -> Measurement {
    Measurement {
        frame,
        timestamp_ns: Timestamp::from_frame(frame, 200.0),
        camera,
        rod,
        position_mm: -12.345_67 + rod as f64,
        angle_rad: 1.234_567_8,
        angle_unwrapped_rad: 7.517_753_1,
        velocity_mm_s: -250.125,
        angular_velocity_rad_s: 60.5,
        quality: 0.95,
        status: Status::Ok,
        turns_known: true,
    }
}

fn sample_rows() -> Vec<Measurement> {
    let mut unknown = row(10, CameraId::Camera(1), 3);
    unknown.turns_known = false;
    let mut v = vec![
        row(10, CameraId::Camera(0), 0),
        unknown,
        row(10, CameraId::Fused, 3),
        Measurement::empty(
            11,
            Timestamp::from_secs_f64(0.055),
            CameraId::Camera(0),
            2,
            Status::Occluded,
        ),
    ];
    let mut nan = row(11, CameraId::Camera(1), 5);
    nan.position_mm = f64::NAN;
    v.push(nan);
    v
}

fn assert_close(a: &Measurement, b: &Measurement) {
    let s = a.sanitized();
    assert_eq!(
        (s.frame, s.camera, s.rod, s.status, s.turns_known),
        (b.frame, b.camera, b.rod, b.status, b.turns_known)
    );
    for (x, y, tol) in [
        (s.timestamp_s(), b.timestamp_s(), 1e-9),
        (s.position_mm, b.position_mm, 5e-5),
        (s.angle_rad, b.angle_rad, 5e-7),
        (s.angle_unwrapped_rad, b.angle_unwrapped_rad, 5e-7),
        (s.velocity_mm_s, b.velocity_mm_s, 5e-4),
        (s.angular_velocity_rad_s, b.angular_velocity_rad_s, 5e-5),
        (s.quality, b.quality, 5e-5),
    ] {
        assert!((x - y).abs() <= tol, "{x} vs {y}");
    }
}

#[test]
fn csv_round_trip_with_exact_header_and_no_nan() {
    let dir = tmpdir("csv");
    let path = dir.join("m.csv");
    let rows = sample_rows();
    {
        let mut s = CsvSink::create(&path).unwrap();
        s.write(&rows[..3]).unwrap();
        s.write(&rows[3..]).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), OUTPUT_COLUMNS.join(","));
    assert_eq!(
        lines.next().unwrap(),
        "10,0.050000000,0,0,-12.3457,1.234568,7.517753,-250.125,60.5000,0.9500,ok,true"
    );
    assert!(lines.next().unwrap().ends_with(",ok,false"));
    assert!(text.contains(",fused,3,"));
    assert!(!text.to_lowercase().contains("nan"));
    let back = read_measurements_csv(&path).unwrap();
    assert_eq!(back.len(), rows.len());
    for ((m, vis), r) in back.iter().zip(&rows) {
        assert_eq!(*vis, None);
        assert_close(r, m);
    }
    // The NaN row came back as 0 with a status that says so.
    assert_eq!(back[4].0.position_mm, 0.0);
    assert_eq!(back[4].0.status, Status::NotFound);
}

#[test]
fn jsonl_round_trip() {
    let dir = tmpdir("jsonl");
    let path = dir.join("m.jsonl");
    let rows = sample_rows();
    {
        let mut s = JsonlSink::create(&path).unwrap();
        s.write(&rows).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let first: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    let keys: Vec<&str> = first
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    let mut want = OUTPUT_COLUMNS.to_vec();
    want.sort_unstable();
    let mut keys_sorted = keys.clone();
    keys_sorted.sort_unstable();
    assert_eq!(keys_sorted, want);
    // `camera` is a number, like `rod`; fused rows say "fused".
    assert_eq!(first["camera"], 0);
    assert!(first["rod"].is_u64());
    assert_eq!(first["status"], "ok");
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(v["camera"].is_u64() || v["camera"] == "fused", "{line}");
    }
    let back = read_measurements_jsonl(&path).unwrap();
    assert_eq!(back.len(), rows.len());
    for ((m, _), r) in back.iter().zip(&rows) {
        assert_close(r, m);
    }
}

#[test]
fn csv_reader_accepts_visible_and_reorders_and_names_errors() {
    let p = Path::new("truth.csv");
    let text = "rod,frame,timestamp_s,camera,position_mm,angle_rad,angle_unwrapped_rad,velocity_mm_s,angular_velocity_rad_s,quality,status,visible,note\n\
                2,7,0.035,1,3.5,0.1,0.1,0,0,1,ok,true,x\r\n\
                \n\
                2,8,0.040,fused,3.6,0.2,0.2,0,0,1,occluded,0,y\n";
    let rows = parse_measurements_csv(text, p).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (rows[0].0.rod, rows[0].0.frame, rows[0].1),
        (2, 7, Some(true))
    );
    assert_eq!(
        (rows[1].0.camera, rows[1].0.status, rows[1].1),
        (CameraId::Fused, Status::Occluded, Some(false))
    );

    let bad = text.replace("0.2,0.2", "0.2,abc");
    let e = parse_measurements_csv(&bad, p).unwrap_err().to_string();
    assert!(
        e.contains("truth.csv") && e.contains("line 4") && e.contains("angle_unwrapped_rad"),
        "{e}"
    );
    let bad = text.replace(",ok,", ",fine,");
    let e = parse_measurements_csv(&bad, p).unwrap_err().to_string();
    assert!(
        e.contains("line 2") && e.contains("status") && e.contains("fine"),
        "{e}"
    );
    let bad = text.replace("visible", "seen").replace(",true,", ",maybe,");
    assert!(
        parse_measurements_csv(&bad, p).is_ok(),
        "unknown columns are ignored"
    );
    let bad = text.replace("quality,", "");
    let e = parse_measurements_csv(&bad, p).unwrap_err().to_string();
    assert!(
        e.contains("line 1") && e.contains("quality") && e.contains("missing column"),
        "{e}"
    );
    let bad = text.replace("0,1,ok,true,x", "0,1,ok,true");
    let e = parse_measurements_csv(&bad, p).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("12 fields"), "{e}");
    let e = read_measurements_csv(Path::new("/nonexistent/truth.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/truth.csv"), "{e}");
}

#[test]
fn rows_written_before_a_crash_are_on_disk() {
    let dir = tmpdir("crash");
    let csv = dir.join("m.csv");
    let jsonl = dir.join("m.jsonl");
    let (c2, j2) = (csv.clone(), jsonl.clone());
    let rows = sample_rows();
    let r2 = rows.clone();
    let res = std::thread::spawn(move || {
        let mut c = CsvSink::create(&c2).unwrap();
        let mut j = JsonlSink::create(&j2).unwrap();
        // Offline setting: no flush per write, so only drop-on-unwind can save the rows.
        c.set_flush_each_write(false);
        j.set_flush_each_write(false);
        c.write(&r2).unwrap();
        j.write(&r2).unwrap();
        panic!("simulated failure");
    })
    .join();
    assert!(res.is_err());
    assert_eq!(read_measurements_csv(&csv).unwrap().len(), rows.len());
    assert_eq!(read_measurements_jsonl(&jsonl).unwrap().len(), rows.len());
}

/// A writer that fails after `limit` bytes.
struct Failing {
    inner: Vec<u8>,
    limit: usize,
}
impl Write for Failing {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.inner.len() + buf.len() > self.limit {
            return Err(std::io::Error::other("disk full"));
        }
        self.inner.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_failing_writer_gives_an_error_naming_the_file() {
    let w = Failing {
        inner: Vec::new(),
        limit: 400,
    };
    let mut s = CsvSink::new(w, "out/m.csv").unwrap();
    s.write(&sample_rows()[..1]).unwrap();
    let mut err = None;
    for _ in 0..20 {
        if let Err(e) = s.write(&sample_rows()) {
            err = Some(e);
            break;
        }
    }
    let e = err.unwrap().to_string();
    assert!(e.contains("out/m.csv") && e.contains("disk full"), "{e}");
}

#[test]
fn udp_round_trip_on_loopback() {
    let rx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .unwrap();
    let addr = rx.local_addr().unwrap().to_string();
    let mut sink = UdpSink::new(&addr).unwrap();
    let rows = sample_rows();
    // Two frames in one call: two datagrams.
    sink.write(&rows).unwrap();
    sink.flush().unwrap();
    let mut buf = [0u8; 65536];
    let n = rx.recv(&mut buf).unwrap();
    assert_eq!(n, UDP_HEADER_BYTES + 3 * UDP_ROW_BYTES);
    let p = decode_udp_packet(&buf[..n]).unwrap();
    assert_eq!(
        (p.version, p.seq, p.frame, p.timestamp_ns),
        (2, 0, 10, 50_000_000)
    );
    assert_eq!(p.rows.len(), 3);
    for (a, b) in rows[..3].iter().zip(&p.rows) {
        assert_eq!(
            (a.camera, a.rod, a.status, a.turns_known),
            (b.camera, b.rod, b.status, b.turns_known)
        );
        assert_eq!(a.position_mm, b.position_mm);
        assert_eq!(a.angle_unwrapped_rad, b.angle_unwrapped_rad);
        assert!((a.quality - b.quality).abs() < 1e-6);
    }
    let n = rx.recv(&mut buf).unwrap();
    let p = decode_udp_packet(&buf[..n]).unwrap();
    assert_eq!((p.seq, p.frame, p.rows.len()), (1, 11, 2));
    assert_eq!(p.rows[0].status, Status::Occluded);
    assert_eq!(p.rows[1].position_mm, 0.0, "NaN is sent as 0");
    assert_eq!(p.rows[1].status, Status::NotFound);
}

#[test]
fn udp_layout_is_fixed_and_decoder_rejects_garbage() {
    let mut out = Vec::new();
    encode_udp_packet(7, &[row(3, CameraId::Fused, 2)], &mut out).unwrap();
    assert_eq!(&out[0..4], b"RTRK");
    assert_eq!(u16::from_le_bytes([out[4], out[5]]), 2);
    assert_eq!(u16::from_le_bytes([out[6], out[7]]), 1);
    assert_eq!(u32::from_le_bytes(out[8..12].try_into().unwrap()), 7);
    assert_eq!(u64::from_le_bytes(out[16..24].try_into().unwrap()), 3);
    assert_eq!(
        u64::from_le_bytes(out[24..32].try_into().unwrap()),
        15_000_000
    );
    assert_eq!(
        u32::from_le_bytes(out[32..36].try_into().unwrap()),
        u32::MAX
    );
    assert_eq!(u32::from_le_bytes(out[36..40].try_into().unwrap()), 2);
    assert_eq!(
        f64::from_le_bytes(out[40..48].try_into().unwrap()),
        -10.345_67
    );
    assert_eq!(out[32 + 52], 0);
    // Flags: bit 0 turns_known.
    assert_eq!(out[32 + 53], 1);
    assert_eq!(&out[32 + 54..32 + 56], &[0, 0]);
    let mut unknown = row(3, CameraId::Fused, 2);
    unknown.turns_known = false;
    unknown.status = Status::Conflict;
    let mut two = Vec::new();
    encode_udp_packet(8, &[unknown], &mut two).unwrap();
    assert_eq!((two[32 + 52], two[32 + 53]), (7, 0));
    let back = decode_udp_packet(&two).unwrap();
    assert_eq!(
        (back.rows[0].status, back.rows[0].turns_known),
        (Status::Conflict, false)
    );
    // A version 1 datagram (flags byte reserved, 0) reads as turns_known.
    let mut v1 = two.clone();
    v1[4] = 1;
    v1[32 + 52] = 0;
    let back = decode_udp_packet(&v1).unwrap();
    assert_eq!((back.version, back.rows[0].turns_known), (1, true));
    let mut v3 = out.clone();
    v3[4] = 3;
    assert!(decode_udp_packet(&v3).is_err());
    assert!(decode_udp_packet(&out[..out.len() - 1]).is_err());
    let mut bad = out.clone();
    bad[0] = b'X';
    assert!(decode_udp_packet(&bad)
        .unwrap_err()
        .to_string()
        .contains("magic"));
    let mut bad = out.clone();
    bad[32 + 52] = 99;
    assert!(decode_udp_packet(&bad)
        .unwrap_err()
        .to_string()
        .contains("status"));
}

#[test]
fn files_written_before_turns_known_read_as_known() {
    // CSV and JSON Lines rows of the old format (no turns_known): read as known.
    let csv = "frame,timestamp_s,camera,rod,position_mm,angle_rad,angle_unwrapped_rad,\
               velocity_mm_s,angular_velocity_rad_s,quality,status\n\
               3,0.015,0,1,1.5,0.5,6.78,0,0,0.95,ok\n";
    let rows = parse_measurements_csv(csv, Path::new("old.csv")).unwrap();
    assert!(rows[0].0.turns_known);
    // New files: both values, and a bad value is named.
    let csv = "frame,timestamp_s,camera,rod,position_mm,angle_rad,angle_unwrapped_rad,\
               velocity_mm_s,angular_velocity_rad_s,quality,status,turns_known\n\
               3,0.015,0,1,1.5,0.5,6.78,0,0,0.95,ok,false\n\
               4,0.020,0,1,1.5,0.5,6.78,0,0,0.95,conflict,true\n";
    let rows = parse_measurements_csv(csv, Path::new("new.csv")).unwrap();
    assert!(!rows[0].0.turns_known);
    assert!(rows[1].0.turns_known);
    assert_eq!(rows[1].0.status, Status::Conflict);
    let bad = csv.replace("ok,false", "ok,maybe");
    let e = parse_measurements_csv(&bad, Path::new("new.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("turns_known") && e.contains("line 2"), "{e}");
    let dir = tmpdir("old-jsonl");
    let path = dir.join("old.jsonl");
    std::fs::write(
        &path,
        r#"{"frame":3,"timestamp_s":0.015,"camera":0,"rod":1,"position_mm":1.5,"angle_rad":0.5,"angle_unwrapped_rad":6.78,"velocity_mm_s":0,"angular_velocity_rad_s":0,"quality":0.95,"status":"ok"}
{"frame":4,"timestamp_s":0.02,"camera":0,"rod":1,"position_mm":1.5,"angle_rad":0.5,"angle_unwrapped_rad":6.78,"velocity_mm_s":0,"angular_velocity_rad_s":0,"quality":0.95,"status":"predicted","turns_known":false}
"#,
    )
    .unwrap();
    let rows = read_measurements_jsonl(&path).unwrap();
    assert!(rows[0].0.turns_known);
    assert!(!rows[1].0.turns_known);
}
