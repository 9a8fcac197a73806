//! The built-in simulator as a frame source: `sim://SCENARIO?camera=N&frames=M&seed=S&realtime=1`.
//!
//! Each source renders the frames of one camera of the reference table on demand, into the
//! pipeline's pooled buffer; frame id and timestamp come from the simulator. Parameters:
//!
//! | key | default | meaning |
//! |---|---|---|
//! | `camera` | 0 | camera index of the simulated table |
//! | `frames` | the scenario's length | number of frames |
//! | `seed` | 1 | scene variations and sensor noise, as `rodtrack simulate --seed` |
//! | `realtime` | 0 | 1: release frame `k` at `k / fps` after the first trigger, report `live` |
//! | `quality` | 0 | 1: quality rendering, as `rodtrack simulate --quality` |
//! | `every` | 1 | `K` > 1: deliver frames `0, K, 2K, ...` only (with their ids and timestamps), as a camera at 1/K of the frame rate |
//! | `loop` | 0 | 1: endless: frame `k` shows the scenario's frame `k % frames` (frame ids and timestamps keep counting) |
//! | `trigger_unix_ms` | none | with `realtime=1`: frame `k` is triggered at this Unix time (ms, the system clock) plus `k / fps`, as one hardware trigger shared by every process on the machine (camera nodes of a network, see docs/network.md); a source opened after that time starts at the next trigger, with its frame id |
//! | `prerender` | 0 | `K` > 0: render frames `0..K` when opened and deliver frame `i` with the pixels of frame `i % K` (for latency measurements: the host CPU then only copies frames, as with a camera) |
//!
//! The frames are byte for byte those `rodtrack simulate` writes as PNG for the same scenario,
//! frame count and seed (both build the simulation with [`crate::build_simulation`]).
//!
//! Several sources of the same simulation (same scenario, frames, seed, quality) opened from
//! one factory are hardware-synchronised: they share one simulation, built once, so they
//! deliver the same frame ids. In real time they also share one trigger: frame `k` is rendered
//! ahead and released at `k / fps` after the trigger of frame 0 (50 ms after the first call of
//! any of them), and, like a trigger gated on every
//! camera being ready, no camera starts frame `k` before the others have delivered frame
//! `k - 1 - LEAD` ([`LEAD`] frames of slack). A frame that cannot be rendered by its trigger
//! time (the simulator renders on the host CPU; a real camera does not) is delivered late,
//! never skipped, so the cameras stay in step and deliver every frame id; the lag shows in the
//! frame rate and the latency.

use crate::Simulation;
use rodtrack_core::PixelFormat;
use rodtrack_io::source::{InputSpec, OpenOptions, SourceInfo};
use rodtrack_io::{FrameBuffer, FrameSource, IoError, SourceError, SourceFactory, Timestamp};
use std::collections::HashMap;
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// What makes two sim sources parts of the same simulation.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct SimKey {
    scenario: String,
    frames: Option<usize>,
    seed: u64,
    quality: bool,
}

/// One simulation shared by the sources (cameras) opened on it.
struct Shared {
    /// The prepared simulation; each source renders with its own clone (renderers keep
    /// per-camera scratch state, so cameras render in parallel without a lock).
    sim: Simulation,
    /// The trigger clock of real-time sources: the time of frame 0.
    epoch: OnceLock<Instant>,
    /// Per real-time source opened on this simulation: the number of frames it delivered
    /// (`u64::MAX` once it ended or was dropped).
    delivered: Mutex<Vec<u64>>,
    /// Signalled when an entry of `delivered` grows.
    progress: Condvar,
}

/// How many frames a real-time camera may run ahead of the slowest one.
pub const LEAD: u64 = 2;

/// Longest wait for a lagging camera before a frame is released anyway (a camera that stopped
/// reading must not stop the others).
const MAX_GATE_WAIT: Duration = Duration::from_millis(500);

impl Shared {
    /// Registers a real-time source; returns its slot.
    fn join(&self) -> usize {
        let mut d = self.delivered.lock().unwrap_or_else(|e| e.into_inner());
        d.push(0);
        d.len() - 1
    }

    /// Waits until every other real-time source delivered frame `index - 1 - LEAD`.
    fn gate(&self, index: u64) {
        let need = index.saturating_sub(LEAD);
        let deadline = Instant::now() + MAX_GATE_WAIT;
        let mut d = self.delivered.lock().unwrap_or_else(|e| e.into_inner());
        while d.iter().any(|&n| n < need) {
            let now = Instant::now();
            if now >= deadline {
                return;
            }
            d = match self.progress.wait_timeout(d, deadline - now) {
                Ok((d, _)) => d,
                Err(e) => e.into_inner().0,
            };
        }
    }

    /// Records that slot `slot` delivered `count` frames.
    fn delivered(&self, slot: usize, count: u64) {
        let mut d = self.delivered.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(n) = d.get_mut(slot) {
            *n = count;
        }
        drop(d);
        self.progress.notify_all();
    }
}

/// Simulations already built by one factory, by key.
type Cache = Arc<Mutex<HashMap<SimKey, Arc<Shared>>>>;

/// Registers the `sim` scheme in `factory`.
pub fn register_sim_source(factory: &mut SourceFactory) {
    let cache: Cache = Arc::new(Mutex::new(HashMap::new()));
    factory.register(
        "sim",
        Box::new(move |spec, opts| {
            SimSource::open(spec, opts, &cache).map(|s| Box::new(s) as Box<dyn FrameSource>)
        }),
    );
}

/// How a simulated camera delivers its frames (the `sim://` parameters of the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Playback {
    /// Release frame `k` at `k / fps` after the first trigger, and report `live`.
    pub realtime: bool,
    /// Endless: frame `k` shows the scenario's frame `k % frames`.
    pub looping: bool,
    /// Deliver every `every`-th frame of the timeline (at least 1).
    pub every: usize,
    /// Render frames `0..prerender` when opened and cycle through them.
    pub prerender: usize,
    /// With `realtime`: frame `k` is triggered at this Unix time in ms plus `k / fps` (the
    /// system clock, shared by processes), instead of 50 ms after the first read.
    pub trigger_unix_ms: Option<u64>,
}

impl Default for Playback {
    fn default() -> Self {
        Playback {
            realtime: false,
            looping: false,
            every: 1,
            prerender: 0,
            trigger_unix_ms: None,
        }
    }
}

/// One simulated camera; see the module documentation.
pub struct SimSource {
    name: String,
    sim: Simulation,
    shared: Arc<Shared>,
    camera: usize,
    next: usize,
    frames: usize,
    width: usize,
    height: usize,
    format: PixelFormat,
    fps: f64,
    realtime: bool,
    /// Deliver every `every`-th frame of the timeline.
    every: usize,
    /// Endless: the scenario's frames over again.
    looping: bool,
    /// Slot in `shared.delivered` (real time only).
    slot: Option<usize>,
    /// How long the last frame took to render or copy.
    prep: Duration,
    /// Frames rendered when opened (`prerender`), with their metadata.
    prerendered: Vec<(crate::RenderInfo, Vec<u8>)>,
    /// The shared trigger clock (`trigger_unix_ms`), ns since the Unix epoch, and whether the
    /// first frame (the next trigger after opening) was chosen yet.
    trigger_unix_ns: Option<u64>,
    trigger_started: bool,
}

/// Most bytes `prerender` may hold per source.
const MAX_PRERENDER_BYTES: usize = 2 << 30;

impl Drop for SimSource {
    fn drop(&mut self) {
        if let Some(slot) = self.slot {
            self.shared.delivered(slot, u64::MAX);
        }
    }
}

impl std::fmt::Debug for SimSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimSource")
            .field("name", &self.name)
            .field("camera", &self.camera)
            .field("next", &self.next)
            .field("frames", &self.frames)
            .field("realtime", &self.realtime)
            .finish()
    }
}

fn flag(spec: &InputSpec, key: &str) -> Result<bool, IoError> {
    match spec.param(key) {
        None | Some("0") | Some("false") | Some("no") => Ok(false),
        Some("1") | Some("true") | Some("yes") => Ok(true),
        Some(v) => Err(IoError::BadInput {
            input: spec.input.clone(),
            reason: format!("parameter `{key}`: expected 0 or 1, got `{v}`"),
        }),
    }
}

impl SimSource {
    /// Opens camera `camera` of the simulation the input names, building the simulation (about
    /// a second) unless `cache` already holds it.
    fn open(spec: &InputSpec, opts: &OpenOptions, cache: &Cache) -> Result<SimSource, IoError> {
        spec.check_params(&[
            "camera",
            "frames",
            "seed",
            "realtime",
            "quality",
            "prerender",
            "every",
            "loop",
            "trigger_unix_ms",
        ])?;
        let bad = |reason: String| IoError::BadInput {
            input: spec.input.clone(),
            reason,
        };
        let camera: usize = spec.param_parse("camera")?.unwrap_or(0);
        let frames: Option<usize> = spec.param_parse("frames")?;
        if frames == Some(0) {
            return Err(bad("parameter `frames` must be at least 1".into()));
        }
        let key = SimKey {
            scenario: spec.target.clone(),
            frames,
            seed: spec.param_parse("seed")?.unwrap_or(1),
            quality: flag(spec, "quality")?,
        };
        let realtime = flag(spec, "realtime")?;
        let looping = flag(spec, "loop")?;
        let every: usize = spec.param_parse("every")?.unwrap_or(1);
        if every == 0 {
            return Err(bad("parameter `every` must be at least 1".into()));
        }
        let shared = {
            let mut map = cache
                .lock()
                .map_err(|_| bad("simulator cache poisoned".into()))?;
            match map.get(&key) {
                Some(s) => s.clone(),
                None => {
                    let sim = crate::build_simulation(
                        &key.scenario,
                        key.frames,
                        key.seed,
                        key.quality,
                        "default",
                    )
                    .map_err(|e| bad(e.to_string()))?;
                    let s = Arc::new(Shared {
                        sim,
                        epoch: OnceLock::new(),
                        delivered: Mutex::new(Vec::new()),
                        progress: Condvar::new(),
                    });
                    map.insert(key.clone(), s.clone());
                    s
                }
            }
        };
        let how = Playback {
            realtime,
            looping,
            every,
            prerender: spec.param_parse("prerender")?.unwrap_or(0),
            trigger_unix_ms: spec.param_parse("trigger_unix_ms")?,
        };
        if how.trigger_unix_ms.is_some() && !realtime {
            return Err(bad(
                "parameter `trigger_unix_ms` needs `realtime=1` (it sets the real-time trigger)"
                    .into(),
            ));
        }
        Self::on_shared(shared, camera, opts, how, &spec.input)
    }

    /// One source per camera of `sim` (a simulation already built), sharing it as the sources
    /// of one `sim://` URI do, delivering their frames as `playback` says.
    pub fn for_simulation(sim: &Simulation, playback: Playback) -> Result<Vec<SimSource>, IoError> {
        let shared = Arc::new(Shared {
            sim: sim.clone(),
            epoch: OnceLock::new(),
            delivered: Mutex::new(Vec::new()),
            progress: Condvar::new(),
        });
        let how = Playback {
            every: playback.every.max(1),
            ..playback
        };
        (0..sim.cameras().len())
            .map(|c| {
                let name = format!("simulated camera {c}");
                Self::on_shared(shared.clone(), c, &OpenOptions::default(), how, &name)
            })
            .collect()
    }

    /// Camera `camera` of the shared simulation.
    fn on_shared(
        shared: Arc<Shared>,
        camera: usize,
        opts: &OpenOptions,
        how: Playback,
        name: &str,
    ) -> Result<SimSource, IoError> {
        let bad = |reason: String| IoError::BadInput {
            input: name.to_string(),
            reason,
        };
        let count = shared.sim.cameras().len();
        let cam = shared.sim.cameras().get(camera).ok_or_else(|| {
            bad(format!(
                "parameter `camera`: camera {camera} does not exist (the simulated table has {count}: 0..{})",
                count.saturating_sub(1)
            ))
        })?;
        let (width, height, format) = (cam.camera.width, cam.camera.height, cam.pixel_format);
        if let Some(want) = opts.format {
            if want != format {
                return Err(bad(format!(
                    "simulated camera {camera} delivers {} frames, {} expected (calibration or `format`)",
                    format.name(),
                    want.name()
                )));
            }
        }
        if let Some((w, h)) = opts.size {
            if (w, h) != (width, height) {
                return Err(bad(format!(
                    "simulated camera {camera} delivers {width}x{height} frames, {w}x{h} expected (calibration)"
                )));
            }
        }
        let fps = shared.sim.scenario().fps;
        let bytes = cam.frame_bytes();
        let mut sim = shared.sim.clone();
        let prerender = how.prerender.min(sim.frame_count());
        if prerender.saturating_mul(bytes) > MAX_PRERENDER_BYTES {
            return Err(bad(format!(
                "parameter `prerender`: {prerender} frames of {bytes} bytes exceed {} MiB",
                MAX_PRERENDER_BYTES >> 20
            )));
        }
        let mut prerendered = Vec::with_capacity(prerender);
        for i in 0..prerender {
            let mut data = vec![0u8; bytes];
            let meta = sim
                .render(i, camera, &mut data)
                .map_err(|e| bad(format!("rendering frame {i}: {e}")))?;
            prerendered.push((meta, data));
        }
        let slot = how.realtime.then(|| shared.join());
        Ok(SimSource {
            slot,
            prep: Duration::ZERO,
            prerendered,
            name: name.to_string(),
            frames: sim.frame_count(),
            sim,
            shared,
            camera,
            next: 0,
            width,
            height,
            format,
            fps,
            realtime: how.realtime,
            every: how.every,
            looping: how.looping,
            trigger_unix_ns: how
                .trigger_unix_ms
                .filter(|_| how.realtime)
                .map(|ms| ms.saturating_mul(1_000_000)),
            trigger_started: false,
        })
    }

    /// Frames delivered in all (`None`: endless).
    fn delivered_count(&self) -> Option<usize> {
        (!self.looping).then(|| self.frames.div_ceil(self.every))
    }
}

impl FrameSource for SimSource {
    fn info(&self) -> SourceInfo {
        SourceInfo {
            name: self.name.clone(),
            width: self.width,
            height: self.height,
            format: self.format,
            fps: Some(self.fps),
            frame_count: self.delivered_count().map(|n| n as u64),
            live: self.realtime,
        }
    }

    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, SourceError> {
        if let (Some(t0), false) = (self.trigger_unix_ns, self.trigger_started) {
            // Opened after the shared trigger started: begin at the next trigger.
            self.trigger_started = true;
            let late_ns = unix_now_ns().saturating_sub(t0);
            let period_ns = 1e9 / self.fps * self.every as f64;
            self.next = (late_ns as f64 / period_ns).ceil() as usize;
        }
        if self.delivered_count().is_some_and(|n| self.next >= n) {
            if let Some(slot) = self.slot {
                self.shared.delivered(slot, u64::MAX);
            }
            return Ok(None);
        }
        // `tick`: the frame's place on the (endless) timeline; `index`: the scenario's frame
        // it shows.
        let tick = self.next * self.every;
        let index = tick % self.frames.max(1);
        self.next += 1;
        let failed = |e: crate::SimError| IoError::SourceFailed {
            name: self.name.clone(),
            reason: format!("frame {index}: {e}"),
        };
        // Real time: frame `index` is triggered at `due`; it is prepared (rendered or copied)
        // just before, so that the preparation does not compete for the CPU with the
        // tracking of the previous frame.
        let due = self.realtime.then(|| {
            least_timer_slack();
            if let Some(t0) = self.trigger_unix_ns {
                // The shared clock keeps the cameras in step: no gate between them.
                let due_unix = t0 + (tick as f64 * 1e9 / self.fps).round() as u64;
                let due =
                    Instant::now() + Duration::from_nanos(due_unix.saturating_sub(unix_now_ns()));
                let period = Duration::from_secs_f64(1.0 / self.fps);
                let lead = (2 * self.prep + Duration::from_micros(200)).min(period);
                sleep_until(due.checked_sub(lead).unwrap_or(due));
                return due;
            }
            self.shared.gate(self.next as u64 - 1);
            let epoch = *self
                .shared
                .epoch
                .get_or_init(|| Instant::now() + Duration::from_millis(50));
            let due = epoch + Duration::from_secs_f64(tick as f64 / self.fps);
            let period = Duration::from_secs_f64(1.0 / self.fps);
            let lead = (2 * self.prep + Duration::from_micros(200)).min(period);
            sleep_until(due.checked_sub(lead).unwrap_or(due));
            due
        });
        let prep_start = Instant::now();
        buf.reshape_packed(self.width, self.height, self.format);
        let meta = if self.prerendered.is_empty() {
            self.sim
                .render(index, self.camera, &mut buf.data)
                .map_err(failed)?
        } else {
            let (m, data) = &self.prerendered[index % self.prerendered.len()];
            let n = data.len().min(buf.data.len());
            buf.data[..n].copy_from_slice(&data[..n]);
            crate::RenderInfo {
                frame_id: index as u64,
                timestamp_ns: self.sim.timestamp(index),
                ..*m
            }
        };
        if (meta.width, meta.height, meta.format) != (self.width, self.height, self.format) {
            return Err(IoError::SourceFailed {
                name: self.name.clone(),
                reason: format!(
                    "frame {index}: rendered {}x{} {}, announced {}x{} {}",
                    meta.width,
                    meta.height,
                    meta.format.name(),
                    self.width,
                    self.height,
                    self.format.name()
                ),
            });
        }
        buf.reshape(meta.width, meta.height, meta.stride, meta.format);
        if tick == index {
            buf.meta.frame_id = meta.frame_id;
            buf.meta.timestamp_ns = meta.timestamp_ns;
        } else {
            // A loop's later rounds: the timeline goes on.
            buf.meta.frame_id = tick as u64;
            buf.meta.timestamp_ns = Timestamp::from_frame(tick as u64, self.fps);
        }
        self.prep = prep_start.elapsed();
        if let Some(due) = due {
            // Released at its trigger time, as a camera delivers it (exposure and readout are
            // not modelled). Frame 0 is triggered 50 ms after the first call of any camera.
            sleep_until(due);
        }
        if let Some(slot) = self.slot {
            self.shared.delivered(slot, self.next as u64);
        }
        Ok(Some(()))
    }
}

/// The system clock, ns since the Unix epoch (0 before it).
fn unix_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Lets the calling thread's sleeps end as close to their deadline as the kernel can: a
/// camera delivers its frame at its trigger, and Linux lets a sleeping thread wake up to its
/// timer slack late (50 us by default), on top of the scheduler's own delay (measured on a
/// 2-core virtual machine, 4.7 ms sleeps: 102 us late at the median with the default slack,
/// 40 us with the least). Elsewhere a no-op.
fn least_timer_slack() {
    #[cfg(target_os = "linux")]
    // SAFETY: `prctl(PR_SET_TIMERSLACK, n)` takes plain integers and changes only the
    // calling thread's timer slack; it touches no memory of ours.
    #[allow(unsafe_code)]
    unsafe {
        libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong);
    }
}

fn sleep_until(t: Instant) {
    let now = Instant::now();
    if t > now {
        std::thread::sleep(t - now);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn factory() -> SourceFactory {
        let mut f = SourceFactory::new();
        register_sim_source(&mut f);
        f
    }

    #[test]
    fn two_cameras_share_frame_ids_and_match_the_simulation() {
        let f = factory();
        let o = OpenOptions::default();
        let mut a = f.open("sim://exp3?camera=0&frames=3&seed=2", &o).unwrap();
        let mut b = f.open("sim://exp3?camera=1&frames=3&seed=2", &o).unwrap();
        assert!(!a.info().live);
        assert_eq!(a.info().frame_count, Some(3));
        let mut sim = crate::build_simulation("exp3", Some(3), 2, false, "default").unwrap();
        let mut want = vec![0u8; sim.frame_bytes(1).unwrap()];
        let (mut fa, mut fb) = (FrameBuffer::new(), FrameBuffer::new());
        for i in 0..3u64 {
            a.next_frame(&mut fa).unwrap().unwrap();
            b.next_frame(&mut fb).unwrap().unwrap();
            assert_eq!(fa.meta.frame_id, i);
            assert_eq!(fb.meta.frame_id, i);
            assert_eq!(fa.meta.timestamp_ns, fb.meta.timestamp_ns);
            assert_eq!(fa.meta.timestamp_ns, Timestamp::from_frame(i, 200.0));
            sim.render(i as usize, 1, &mut want).unwrap();
            assert!(fb.data == want, "frame {i} differs from the simulation");
            fb.view().unwrap();
        }
        assert!(a.next_frame(&mut fa).unwrap().is_none());
        assert!(a.next_frame(&mut fa).unwrap().is_none());
    }

    #[test]
    fn bad_parameters_are_named() {
        let f = factory();
        let o = OpenOptions::default();
        let msg = |s: &str| f.open(s, &o).unwrap_err().to_string();
        assert!(msg("sim://exp3?camera=9&frames=2").contains("camera 9 does not exist"));
        assert!(msg("sim://exp3?cam=1").contains("unknown parameter `cam`"));
        assert!(msg("sim://nope?frames=2").contains("unknown scenario `nope`"));
        assert!(msg("sim://exp3?realtime=maybe").contains("`realtime`"));
        let o = OpenOptions {
            format: Some(PixelFormat::Mono16),
            ..OpenOptions::default()
        };
        let e = f.open("sim://exp3?frames=2", &o).unwrap_err().to_string();
        assert!(e.contains("mono16 expected"), "{e}");
    }

    #[test]
    fn realtime_is_live_and_paced() {
        let f = factory();
        let mut s = f
            .open("sim://exp3?frames=3&realtime=1", &OpenOptions::default())
            .unwrap();
        assert!(s.info().live);
        let mut b = FrameBuffer::new();
        let t = Instant::now();
        while s.next_frame(&mut b).unwrap().is_some() {}
        // Frames 0, 1, 2 at 0, 5 and 10 ms (200 fps).
        assert!(t.elapsed() >= Duration::from_millis(10));
    }

    #[test]
    fn realtime_cameras_stay_in_step() {
        let f = factory();
        let o = OpenOptions::default();
        let mut a = f
            .open("sim://exp3?camera=0&frames=8&realtime=1", &o)
            .unwrap();
        let mut b = f
            .open("sim://exp3?camera=1&frames=8&realtime=1", &o)
            .unwrap();
        let mut buf = FrameBuffer::new();
        for _ in 0..=LEAD {
            a.next_frame(&mut buf).unwrap().unwrap();
        }
        // Camera 1 has delivered nothing: camera 0 waits for it (until the gate's timeout).
        let t = Instant::now();
        a.next_frame(&mut buf).unwrap().unwrap();
        assert!(t.elapsed() >= MAX_GATE_WAIT / 2, "{:?}", t.elapsed());
        // Once it ended, nothing waits for it.
        drop(b.next_frame(&mut buf));
        drop(b);
        let t = Instant::now();
        while a.next_frame(&mut buf).unwrap().is_some() {}
        assert!(t.elapsed() < MAX_GATE_WAIT, "{:?}", t.elapsed());
    }
}
