//! `rodtrack bench-zenoh` (feature `zenoh`): the camera network's latency across processes on
//! loopback, camera frame to fused row.
//!
//! The command starts, as `rodtrack` processes of its own binary, a fusion node (`fuse
//! --subscribe zenoh --publish zenoh`, listening on `tcp/127.0.0.1:PORT`) and one camera node
//! per camera (`track --publish zenoh --camera camN`, connecting to it), multicast scouting
//! off, as the three-process test runs them. The camera nodes track the real-time simulator
//! (`sim://SCENARIO?...&realtime=1&trigger_unix_ms=T`): frame `k` of every camera is
//! triggered at Unix time `T` plus `k / fps` (200 fps), as by one hardware trigger line. The
//! command subscribes to the fused rows (and the camera nodes' raw rows) in its own zenoh
//! session, connected to the fusion node, and stops the nodes at the end.
//!
//! Definitions:
//! - **capture time**: the frame's trigger time, `T` plus the frame's capture timestamp (the
//!   simulator's timestamps count from frame 0's trigger). The simulated camera hands the
//!   frame over at that time (a timer wake-up, late by tens of us, in the latency, as a
//!   camera's readout and delivery would be).
//! - **received**: the command's subscriber callback got the message (zenoh's thread, the
//!   system clock read before decoding): one more hop after the fusion node published it.
//! - **latency** (per frame set): capture -> the set's fused rows received. All the processes
//!   read one clock (the system clock of this machine).
//! - **camera rows**: capture -> a camera node's raw rows (the fusion's input) received;
//!   **fusion node**: the set's last camera rows received -> its fused rows received (the
//!   fusion node's work and its hop, seen from here).
//! - **rows lost**: fused rows the fusion node published (its final report) and the
//!   subscriber did not receive.

use anyhow::{bail, Context, Result};
use rodtrack_io::runtime::{LatencyHistogram, LatencySummary};
use rodtrack_zenoh::layout::Kind;
use rodtrack_zenoh::net::NetworkOptions;
use rodtrack_zenoh::subscriber::{Received, RowSubscriber};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The latency target, p99 (issue: camera frame to fused row, 2 cameras at 200 frame sets/s).
const TARGET_P99: Duration = Duration::from_micros(500);
/// Frame sets kept waiting for their fused rows in the breakdown (older ones are dropped).
const MAX_PENDING_SETS: usize = 4096;

/// Arguments of `rodtrack bench-zenoh`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Frame sets (frames per camera node; at 200 fps, 1000 are 5 s).
    #[arg(long, default_value_t = 1000)]
    pub frames: u64,
    /// Scenario of the simulator (exp3: 8 rods fused per frame set, as the network tests).
    #[arg(long, default_value = "exp3", value_parser = rodtrack_sim::SCENARIO_NAMES)]
    pub scenario: String,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Distinct frames each camera node renders before the run and cycles through (the host
    /// CPU then only copies frames, as with a camera; the rods jump back at each wrap).
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=2000))]
    pub prerender: u64,
    /// From the nodes' start to the trigger of frame 0, ms: time for every node to start,
    /// render ahead and join the network. A node that is not ready by then starts at a later
    /// frame, which the command reports.
    #[arg(long, default_value_t = 6000)]
    pub start_ms: u64,
    /// The fusion node's `--loss-frames`: a camera silent this many frame periods while the
    /// other sends is lost, and the sets go on without it (incomplete).
    #[arg(long, default_value_t = 3.0)]
    pub loss_frames: f64,
    /// Do not subscribe to the camera nodes' raw rows (no breakdown; the camera nodes then
    /// send to the fusion node only).
    #[arg(long)]
    pub no_breakdown: bool,
    /// The camera nodes' `--preview-fps` (downscaled frames for remote consoles; each one is a
    /// copy and a downscale of a whole frame beside the tracking). Default: the nodes' own.
    #[arg(long)]
    pub preview_fps: Option<f64>,
    /// The table's name in the key expressions.
    #[arg(long, default_value = "bench")]
    pub table: String,
    /// Keep the calibration and the nodes' logs in this folder (default: a temporary folder,
    /// removed at the end).
    #[arg(long)]
    pub dir: Option<PathBuf>,
}

/// What the subscriber saw.
#[derive(Default)]
struct Seen {
    /// Capture -> fused rows received, per complete frame set (both cameras).
    latency: LatencyHistogram,
    /// The same for incomplete sets (a camera lost: the set did not wait for it).
    latency_incomplete: LatencyHistogram,
    /// Capture -> raw rows received, per camera.
    camera: BTreeMap<u32, LatencyHistogram>,
    /// The set's last raw rows received -> its fused rows received.
    fusion: LatencyHistogram,
    /// Frame id -> (cameras whose raw rows came, the last one's receive time, ns).
    pending: BTreeMap<u64, (u64, u64)>,
    fused_rows: u64,
    fused_sets: BTreeSet<u64>,
    incomplete: u64,
    raw_frames: BTreeMap<u32, BTreeSet<u64>>,
    /// Fused messages missing in the sequence numbers.
    seq_gaps: u64,
    last_seq: Option<u32>,
    /// Received before the capture time (clock trouble): counted as 0.
    negative: u64,
    undecodable: u64,
}

fn unix_ns(t: SystemTime) -> u64 {
    t.duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

impl Seen {
    /// Records one message; `trigger_ns`: frame 0's trigger, Unix ns.
    fn record(&mut self, r: Received<'_>, trigger_ns: u64) {
        let recv_ns = unix_ns(r.received);
        let Ok(m) = r.message else {
            self.undecodable += 1;
            return;
        };
        let h = m.header;
        let capture_ns = trigger_ns.saturating_add(h.timestamp_ns.as_nanos());
        if recv_ns < capture_ns {
            self.negative += 1;
        }
        let since_capture = Duration::from_nanos(recv_ns.saturating_sub(capture_ns));
        match h.kind {
            Kind::Fused => {
                if h.complete {
                    self.latency.record(since_capture);
                } else {
                    self.latency_incomplete.record(since_capture);
                }
                self.fused_rows += m.rows.len() as u64;
                self.fused_sets.insert(h.frame);
                self.incomplete += u64::from(!h.complete);
                if let Some(last) = self.last_seq {
                    self.seq_gaps += u64::from(h.seq.wrapping_sub(last).saturating_sub(1));
                }
                self.last_seq = Some(h.seq);
                if let Some((mask, last_ns)) = self.pending.remove(&h.frame) {
                    if mask == h.cameras {
                        self.fusion
                            .record(Duration::from_nanos(recv_ns.saturating_sub(last_ns)));
                    }
                }
            }
            Kind::CameraRaw => {
                let cam = h.cameras.trailing_zeros();
                self.camera.entry(cam).or_default().record(since_capture);
                self.raw_frames.entry(cam).or_default().insert(h.frame);
                let e = self.pending.entry(h.frame).or_insert((0, 0));
                e.0 |= h.cameras;
                e.1 = e.1.max(recv_ns);
                while self.pending.len() > MAX_PENDING_SETS {
                    self.pending.pop_first();
                }
            }
            Kind::CameraRows | Kind::End => {}
        }
    }
}

/// A node process: stderr to a file, killed when dropped.
struct Node {
    name: String,
    child: Option<Child>,
    log: PathBuf,
}

impl Node {
    fn start(name: &str, args: &[String], log: PathBuf) -> Result<Node> {
        let exe = std::env::current_exe().context("the path of this rodtrack binary")?;
        let stderr = std::fs::File::create(&log)
            .with_context(|| format!("cannot create {}", log.display()))?;
        let child = Command::new(exe)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(stderr)
            .spawn()
            .with_context(|| format!("starting the {name}"))?;
        Ok(Node {
            name: name.to_string(),
            child: Some(child),
            log,
        })
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// The log's last lines, for an error message.
    fn tail(&self) -> String {
        let log = self.log();
        let lines: Vec<&str> = log.lines().collect();
        lines[lines.len().saturating_sub(8)..].join("\n")
    }

    /// Waits, at most until `until`, for the process to end; true when it ended successfully.
    fn wait_until(&mut self, until: Instant) -> Result<bool> {
        let Some(child) = self.child.as_mut() else {
            return Ok(true);
        };
        loop {
            if let Some(status) = child.try_wait().context("waiting for a node")? {
                self.child = None;
                return Ok(status.success());
            }
            if Instant::now() >= until {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Asks the process to stop as Ctrl-C does (SIGINT, through `kill`), so that it prints
    /// its report; kills it if it does not end within `limit`. True when it ended cleanly.
    fn interrupt(&mut self, limit: Duration) -> Result<bool> {
        let Some(child) = self.child.as_ref() else {
            return Ok(true);
        };
        let sent = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .is_ok_and(|s| s.success());
        let clean = sent && self.wait_until(Instant::now() + limit)?;
        if !clean {
            self.kill();
        }
        Ok(clean)
    }

    fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Drop for Node {
    fn drop(&mut self) {
        self.kill();
    }
}

/// A temporary folder removed when dropped (unless the user gave it).
struct Folder {
    path: PathBuf,
    remove: bool,
}

impl Drop for Folder {
    fn drop(&mut self) {
        if self.remove {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

fn folder(dir: Option<&Path>) -> Result<Folder> {
    let (path, remove) = match dir {
        Some(d) => (d.to_path_buf(), false),
        None => (
            std::env::temp_dir().join(format!("rodtrack-bench-zenoh-{}", std::process::id())),
            true,
        ),
    };
    std::fs::create_dir_all(&path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(Folder { path, remove })
}

/// The calibration of the simulated table's cameras, written to `path`; their names.
fn write_calibration(args: &Args, path: &Path) -> Result<Vec<String>> {
    let mut sim = rodtrack_sim::build_simulation(
        &args.scenario,
        Some(args.prerender as usize),
        args.seed,
        false,
        "default",
    )?;
    let cameras = (0..sim.cameras().len())
        .map(|c| Ok(rodtrack_sim::calibrate_sim_camera(&mut sim, c, args.seed)?.calibration))
        .collect::<Result<Vec<_>>>()?;
    let names = cameras.iter().map(|c| c.name.clone()).collect();
    let cal = rodtrack_sdk::calibration_file(cameras)?;
    rodtrack_sdk::write_calibration(path, &cal)?;
    Ok(names)
}

fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("finding a free TCP port on 127.0.0.1")?
        .port())
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn line(l: &LatencySummary) -> String {
    format!(
        "p50 {:.0} us, p90 {:.0} us, p99 {:.0} us, max {:.0} us",
        us(l.p50),
        us(l.p90),
        us(l.p99),
        us(l.max)
    )
}

/// The number after `before` in the first line of `log` that has it.
fn number_after(log: &str, before: &str) -> Option<u64> {
    log.lines().find_map(|l| {
        let rest = &l[l.find(before)? + before.len()..];
        rest.split(|c: char| !c.is_ascii_digit())
            .next()?
            .parse()
            .ok()
    })
}

/// Runs the benchmark.
pub fn run(args: Args) -> Result<()> {
    crate::interrupt::catch_early();
    let stop = Arc::new(AtomicBool::new(false));
    crate::interrupt::install(stop.clone());
    let dir = folder(args.dir.as_deref())?;
    let calib = dir.path.join("table.toml");
    eprintln!(
        "calibrating the simulated cameras of `{}` ...",
        args.scenario
    );
    let names = write_calibration(&args, &calib)?;
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let calib_arg = calib.display().to_string();
    let mut fusion = Node::start(
        "fusion node",
        &s(&[
            "fuse",
            "--calib",
            &calib_arg,
            "--subscribe",
            "zenoh",
            "--publish",
            "zenoh",
            "--zenoh-listen",
            &endpoint,
            "--table",
            &args.table,
            "--loss-frames",
            &args.loss_frames.to_string(),
        ]),
        dir.path.join("fuse.log"),
    )?;

    // The subscriber, connected to the fusion node before any frame.
    let trigger_ns = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let seen = Arc::new(Mutex::new(Seen::default()));
    let net = NetworkOptions {
        connect: vec![endpoint.clone()],
        table: args.table.clone(),
        ..NetworkOptions::default()
    };
    let (t, sn) = (trigger_ns.clone(), seen.clone());
    let mut sub = RowSubscriber::fused(&net, move |r| {
        let t0 = t.load(Ordering::Relaxed);
        sn.lock().unwrap_or_else(|e| e.into_inner()).record(r, t0);
    })
    .context("the benchmark's subscriber")?;
    if !args.no_breakdown {
        sub.add(&format!("rodtrack/{}/cam/*/raw", args.table))?;
    }
    if sub.wait_for_peers(1, Duration::from_secs(20)) == 0 {
        bail!(
            "the fusion node did not join the network on {endpoint} within 20 s:\n{}",
            fusion.tail()
        );
    }

    // The camera nodes, on one trigger `start_ms` ahead.
    let t0_ms = unix_ns(SystemTime::now()) / 1_000_000 + args.start_ms;
    trigger_ns.store(t0_ms * 1_000_000, Ordering::Relaxed);
    let mut cameras = Vec::new();
    for (c, name) in names.iter().enumerate() {
        let input = format!(
            "sim://{}?camera={c}&frames={n}&seed={}&loop=1&prerender={n}&realtime=1&trigger_unix_ms={t0_ms}",
            args.scenario,
            args.seed,
            n = args.prerender
        );
        let mut node_args = s(&[
            "track",
            "--calib",
            &calib_arg,
            "--camera",
            name,
            "--input",
            &input,
            "--max-frames",
            &args.frames.to_string(),
            "--publish",
            "zenoh",
            "--zenoh-connect",
            &endpoint,
            "--table",
            &args.table,
        ]);
        if let Some(fps) = args.preview_fps {
            node_args.extend(["--preview-fps".to_string(), fps.to_string()]);
        }
        cameras.push(Node::start(
            &format!("camera node {name}"),
            &node_args,
            dir.path.join(format!("{name}.log")),
        )?);
    }
    eprintln!(
        "{} camera node(s) and a fusion node on {endpoint} (multicast scouting off): {} frame sets of `{}` at 200 fps from the shared trigger in {} ms ({} pre-rendered frames per camera, cycled){} ...",
        cameras.len(),
        args.frames,
        args.scenario,
        args.start_ms,
        args.prerender,
        if args.no_breakdown {
            ""
        } else {
            "; the camera nodes' raw rows also to this subscriber"
        }
    );
    let run_s = args.frames as f64 / 200.0;
    let until = Instant::now()
        + Duration::from_millis(args.start_ms)
        + Duration::from_secs_f64(run_s * 1.5 + 20.0);
    for cam in &mut cameras {
        while !cam.wait_until(Instant::now() + Duration::from_millis(100))? {
            if stop.load(Ordering::SeqCst) || Instant::now() >= until {
                cam.kill();
                bail!(
                    "the {} did not end {}:\n{}",
                    cam.name,
                    if stop.load(Ordering::SeqCst) {
                        "(interrupted)"
                    } else {
                        "in time"
                    },
                    cam.tail()
                );
            }
        }
    }
    // The last sets' rows on their way.
    std::thread::sleep(Duration::from_millis(300));
    let clean = fusion.interrupt(Duration::from_secs(10))?;
    sub.close();
    let fuse_log = fusion.log();
    let seen = std::mem::take(&mut *seen.lock().unwrap_or_else(|e| e.into_inner()));
    let published = number_after(&fuse_log, "published: ");
    let sets_written = number_after(&fuse_log, "fusion: ");
    let incomplete_written = number_after(&fuse_log, "complete, ");

    // The report.
    let l = seen.latency.summary();
    println!(
        "latency, capture -> fused rows received by a subscriber: {} ({} complete frame sets)",
        line(&l),
        l.count
    );
    let li = seen.latency_incomplete.summary();
    if li.count > 0 {
        println!(
            "  incomplete sets (a camera lost, not waited for): {} ({} sets)",
            line(&li),
            li.count
        );
    }
    for (cam, h) in &seen.camera {
        let name = names.get(*cam as usize).map_or("?", String::as_str);
        println!(
            "  camera {cam} ({name}): capture -> its raw rows received: {}",
            line(&h.summary())
        );
    }
    if !seen.camera.is_empty() {
        println!(
            "  fusion node: the set's last camera rows received -> its fused rows received: {}",
            line(&seen.fusion.summary())
        );
    }
    let lost = published.map(|p| p.saturating_sub(seen.fused_rows));
    println!(
        "rows: {} fused rows published by the fusion node, {} received, {} lost; {} frame sets received ({} incomplete), {} sequence gaps{}",
        published.map_or("?".into(), |p| p.to_string()),
        seen.fused_rows,
        lost.map_or("?".into(), |l| l.to_string()),
        seen.fused_sets.len(),
        seen.incomplete,
        seen.seq_gaps,
        if seen.camera.is_empty() {
            String::new()
        } else {
            let frames: Vec<String> = seen
                .raw_frames
                .iter()
                .map(|(c, f)| format!("camera {c} {}", f.len()))
                .collect();
            format!("; camera frames received: {}", frames.join(", "))
        }
    );
    let first = seen.fused_sets.first().copied();
    if first.is_some_and(|f| f > 0) {
        println!(
            "  the first fused set is frame {}: a node was not ready by the trigger (raise --start-ms)",
            first.unwrap_or_default()
        );
    }
    if seen.negative > 0 || seen.undecodable > 0 {
        println!(
            "  {} message(s) received before their capture time (counted as 0), {} undecodable",
            seen.negative, seen.undecodable
        );
    }
    if let (Some(s), Some(i)) = (sets_written, incomplete_written) {
        println!("  fusion node: {s} frame sets complete, {i} incomplete");
    }
    let p99 = l.p99;
    if l.count > 0 && p99 <= TARGET_P99 {
        println!(
            "target p99 <= {:.0} us: met ({:.0} us)",
            us(TARGET_P99),
            us(p99)
        );
    } else if l.count > 0 {
        println!(
            "target p99 <= {:.0} us: NOT met, p99 is {:.0} us ({:.0} us over, x{:.1})",
            us(TARGET_P99),
            us(p99),
            us(p99) - us(TARGET_P99),
            us(p99) / us(TARGET_P99)
        );
    }
    if !clean {
        bail!(
            "the fusion node did not end cleanly on SIGINT:\n{}",
            fusion.tail()
        );
    }
    if seen.fused_rows == 0 {
        bail!("no fused rows received:\n{fuse_log}");
    }
    match lost {
        Some(0) => Ok(()),
        Some(n) => bail!("{n} fused row(s) lost between the fusion node and the subscriber"),
        None => bail!("the fusion node did not report what it published:\n{fuse_log}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_from_the_fusion_report() {
        let log = "fusion: 400 frame sets complete, 2 incomplete, 9000 rows written\n  published: 3216 fused rows of 402 frame sets\n";
        assert_eq!(number_after(log, "published: "), Some(3216));
        assert_eq!(number_after(log, "fusion: "), Some(400));
        assert_eq!(number_after(log, "complete, "), Some(2));
        assert_eq!(number_after(log, "nothing "), None);
    }
}
