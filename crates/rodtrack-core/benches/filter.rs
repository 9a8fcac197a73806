//! Cost of the temporal filter and the fusion per rod and frame: a steady track, a track whose
//! measurements are all rejected (coasting plus candidate), and the fusion of two cameras.
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{criterion_group, criterion_main, Criterion};
use rodtrack_core::angle::wrap_2pi;
use rodtrack_core::filter::{FilterBank, FilterConfig, RodFilter};
use rodtrack_core::fusion::{Fuser, FusionConfig};
use rodtrack_core::Timestamp;
use rodtrack_core::{CameraId, Measurement, Status};
use std::hint::black_box;

const DT: f64 = 0.005;

fn row(cam: u32, rod: u32, i: u64) -> Measurement {
    // A deterministic wobble stands in for noise.
    let t = i as f64 * DT;
    let n = ((i.wrapping_mul(0x9E37_79B9) >> 7) % 1000) as f64 / 1000.0 - 0.5;
    Measurement {
        frame: i,
        timestamp_ns: Timestamp::from_secs_f64(t),
        camera: CameraId::Camera(cam),
        rod,
        position_mm: 40.0 * (3.0 * t).sin() + 0.3 * n,
        angle_rad: wrap_2pi(20.0 * t + 0.01 * n),
        angle_unwrapped_rad: 0.0,
        velocity_mm_s: 0.0,
        angular_velocity_rad_s: 0.0,
        quality: 0.9,
        status: Status::Ok,
        turns_known: true,
    }
}

fn bench(c: &mut Criterion) {
    let n = 4096u64;
    let rows: Vec<Measurement> = (0..n).map(|i| row(0, 0, i)).collect();
    let wrong: Vec<Measurement> = rows
        .iter()
        .map(|m| Measurement {
            angle_rad: wrap_2pi(m.angle_rad + if m.frame % 2 == 0 { 0.8 } else { -0.8 }),
            ..*m
        })
        .collect();
    let mut g = c.benchmark_group("filter");
    g.throughput(criterion::Throughput::Elements(1));

    // One update per iteration; the timestamps keep advancing across iterations.
    let mut f = RodFilter::new(FilterConfig::default());
    let mut i = 0u64;
    g.bench_function("update_tracking", |b| {
        b.iter(|| {
            let mut m = rows[(i % n) as usize];
            m.timestamp_ns = Timestamp::from_secs_f64(i as f64 * DT);
            i += 1;
            black_box(f.update(black_box(&m)))
        })
    });

    // Alternating wrong measurements: every update is gated out and feeds the candidate.
    let mut f = RodFilter::new(FilterConfig::default());
    for m in &rows[..10] {
        f.update(m);
    }
    let mut i = 10u64;
    g.bench_function("update_rejecting", |b| {
        b.iter(|| {
            let src = if i % 4 == 0 { &rows } else { &wrong };
            let mut m = src[(i % n) as usize];
            m.timestamp_ns = Timestamp::from_secs_f64(i as f64 * DT);
            i += 1;
            black_box(f.update(black_box(&m)))
        })
    });

    // Two cameras, 8 rods: fusion plus filtering of one trigger (per-rod cost = time / 8).
    let mut fuser = Fuser::new(FusionConfig::default());
    let mut bank = FilterBank::with_rods(FilterConfig::default(), 0..8);
    let mut trigger = Vec::with_capacity(16);
    let mut out = Vec::with_capacity(8);
    let mut i = 0u64;
    g.throughput(criterion::Throughput::Elements(8));
    g.bench_function("fuse_and_filter_2cams_8rods", |b| {
        b.iter(|| {
            trigger.clear();
            for rod in 0..8 {
                for cam in 0..2 {
                    trigger.push(row(cam, rod, i));
                }
            }
            i += 1;
            out.clear();
            fuser.process(black_box(&trigger), &mut bank, &mut out);
            black_box(out.len())
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
