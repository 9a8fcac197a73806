//! `genicam://ID?...` parameters, validated into [`GenicamOptions`].

use rodtrack_core::PixelFormat;
use rodtrack_io::{InputSpec, IoError, OpenOptions};
use std::time::Duration;

/// How frames are triggered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Trigger {
    /// Free run at the camera's frame rate (`fps` sets it).
    #[default]
    Free,
    /// Software triggers issued by the source itself at `fps`, from a [`crate::TriggerClock`]
    /// (shared by the sources of one `sync` group, so that their frames of one tick form a set).
    Software,
    /// Hardware trigger on input line 0 (slaves of a master camera or an external clock).
    Line0,
}

/// Which clock a frame's timestamp comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimestampSource {
    /// The camera's own timestamp (ns), made monotonic across reconnections.
    #[default]
    Camera,
    /// The host's time when the frame arrived (ns since the Unix epoch): comparable between
    /// cameras without a shared clock.
    Host,
}

/// A validated camera configuration. Everything given is set on the camera at every
/// (re)connection: cameras (the fake one too) keep their settings across connections.
#[derive(Debug, Clone, PartialEq)]
pub struct GenicamOptions {
    /// Device id, serial number, address, or `first`.
    pub id: String,
    /// Pixel format; `None`: the camera's current one.
    pub format: Option<PixelFormat>,
    /// Region of interest width and height, px; `None`: the largest from the offsets.
    pub width: Option<u32>,
    /// See [`GenicamOptions::width`].
    pub height: Option<u32>,
    /// Region offsets, px.
    pub offset_x: u32,
    /// See [`GenicamOptions::offset_x`].
    pub offset_y: u32,
    /// Exposure time, µs (auto exposure is turned off).
    pub exposure_us: Option<f64>,
    /// Gain (auto gain is turned off); an error if the camera has no `Gain`.
    pub gain: Option<f64>,
    /// Frame rate: the camera's in free run, the trigger clock's with software triggers.
    pub fps: Option<f64>,
    /// Trigger mode.
    pub trigger: Trigger,
    /// GigE Vision packet size, bytes; `None`: negotiated (the largest the path allows).
    pub packet_size: Option<u32>,
    /// Stream buffers in the pool (at least 2).
    pub buffers: usize,
    /// Longest wait for one frame before the camera is considered lost (not with `line0`
    /// triggers, where no frame may come for a long time).
    pub frame_timeout: Duration,
    /// Give up (fatal error) after this long without reconnecting; `None`: retry for ever.
    pub give_up_after: Option<Duration>,
    /// Timestamp clock.
    pub timestamps: TimestampSource,
    /// Name of a software-trigger group: sources with the same name share one
    /// [`crate::TriggerClock`] (same fps), so their frames of one tick get the same id.
    pub sync: Option<String>,
}

impl GenicamOptions {
    /// Defaults for camera `id`.
    pub fn new(id: &str) -> Self {
        GenicamOptions {
            id: id.to_string(),
            format: None,
            width: None,
            height: None,
            offset_x: 0,
            offset_y: 0,
            exposure_us: None,
            gain: None,
            fps: None,
            trigger: Trigger::Free,
            packet_size: None,
            buffers: 16,
            frame_timeout: Duration::from_secs(1),
            give_up_after: None,
            timestamps: TimestampSource::Camera,
            sync: None,
        }
    }

    /// The parameters `genicam://ID?...` accepts.
    pub const PARAMS: [&'static str; 17] = [
        "format",
        "width",
        "height",
        "offset_x",
        "offset_y",
        "exposure_us",
        "gain",
        "fps",
        "trigger",
        "packet_size",
        "buffers",
        "timeout_ms",
        "give_up_s",
        "timestamps",
        "sync",
        "id",
        "serial",
    ];

    /// From a parsed input (`genicam://ID?format=BayerRG8&width=1440&...`); the input's
    /// parameters override `defaults` (format, fps, size).
    pub fn from_spec(spec: &InputSpec, defaults: &OpenOptions) -> Result<Self, IoError> {
        spec.check_params(&Self::PARAMS)?;
        let bad = |reason: String| IoError::BadInput {
            input: spec.input.clone(),
            reason,
        };
        let mut o = GenicamOptions::new(spec.target.trim_end_matches('/'));
        if let Some(v) = spec.param("id").or(spec.param("serial")) {
            o.id = v.to_string();
        }
        if o.id.is_empty() {
            return Err(bad(
                "no camera id (use `genicam://first` for the first one)".into(),
            ));
        }
        o.format = spec.param_format()?.or(defaults.format);
        o.width = spec.param_parse("width")?;
        o.height = spec.param_parse("height")?;
        if o.width.is_none() && o.height.is_none() {
            if let Some((w, h)) = defaults.size {
                o.width = u32::try_from(w).ok();
                o.height = u32::try_from(h).ok();
            }
        }
        o.offset_x = spec.param_parse("offset_x")?.unwrap_or(0);
        o.offset_y = spec.param_parse("offset_y")?.unwrap_or(0);
        o.exposure_us = spec.param_parse("exposure_us")?;
        o.gain = spec.param_parse("gain")?;
        o.fps = spec.param_parse("fps")?.or(defaults.fps);
        if let Some(f) = o.fps {
            if !(f.is_finite() && f > 0.0) {
                return Err(bad(format!("parameter `fps`: {f} is not positive")));
            }
        }
        if let Some(e) = o.exposure_us {
            if !(e.is_finite() && e > 0.0) {
                return Err(bad(format!("parameter `exposure_us`: {e} is not positive")));
            }
        }
        o.trigger = match spec
            .param("trigger")
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            None | Some("free") | Some("off") => Trigger::Free,
            Some("software") => Trigger::Software,
            Some("line0") => Trigger::Line0,
            Some(other) => {
                return Err(bad(format!(
                    "parameter `trigger`: `{other}` is not free, software or line0"
                )))
            }
        };
        o.packet_size = spec.param_parse("packet_size")?;
        o.buffers = spec.param_parse::<usize>("buffers")?.unwrap_or(16).max(2);
        if let Some(ms) = spec.param_parse::<u64>("timeout_ms")? {
            o.frame_timeout = Duration::from_millis(ms.max(1));
        }
        o.give_up_after = spec
            .param_parse::<f64>("give_up_s")?
            .filter(|s| s.is_finite() && *s > 0.0)
            .map(Duration::from_secs_f64);
        o.timestamps = match spec.param("timestamps") {
            None | Some("camera") => TimestampSource::Camera,
            Some("host") => TimestampSource::Host,
            Some(other) => {
                return Err(bad(format!(
                    "parameter `timestamps`: `{other}` is not camera or host"
                )))
            }
        };
        o.sync = spec.param("sync").map(str::to_string);
        if o.sync.is_some() && o.trigger != Trigger::Software {
            return Err(bad("`sync` needs `trigger=software`".into()));
        }
        if o.trigger == Trigger::Software && o.fps.is_none() {
            return Err(bad(
                "`trigger=software` needs `fps` (the trigger rate)".into()
            ));
        }
        Ok(o)
    }
}

/// The GenICam `PixelFormat` name of a rodtrack format.
pub(crate) fn genicam_format_name(f: PixelFormat) -> &'static str {
    match f {
        PixelFormat::Mono8 => "Mono8",
        PixelFormat::Mono16 => "Mono16",
        PixelFormat::BayerRggb8 => "BayerRG8",
        PixelFormat::BayerBggr8 => "BayerBG8",
        PixelFormat::BayerGrbg8 => "BayerGR8",
        PixelFormat::BayerGbrg8 => "BayerGB8",
        PixelFormat::BayerRggb16 => "BayerRG16",
        PixelFormat::BayerBggr16 => "BayerBG16",
        PixelFormat::BayerGrbg16 => "BayerGR16",
        PixelFormat::BayerGbrg16 => "BayerGB16",
        PixelFormat::Rgb8 => "RGB8",
    }
}

/// The rodtrack format of a GenICam `PixelFormat` name, if it is one rodtrack reads.
pub(crate) fn format_from_genicam(name: &str) -> Option<PixelFormat> {
    match name {
        "RGB8Packed" | "RGB8" => Some(PixelFormat::Rgb8),
        other => PixelFormat::from_name(other),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn parse(s: &str) -> Result<GenicamOptions, IoError> {
        GenicamOptions::from_spec(&InputSpec::parse(s).unwrap(), &OpenOptions::default())
    }

    #[test]
    fn parses_parameters() {
        let o = parse(
            "genicam://Aravis-Fake-GV01?format=BayerRG8&width=720&height=540&offset_x=8\
             &exposure_us=2000&fps=150&trigger=software&packet_size=8192&sync=table",
        )
        .unwrap();
        assert_eq!(o.id, "Aravis-Fake-GV01");
        assert_eq!(o.format, Some(PixelFormat::BayerRggb8));
        assert_eq!((o.width, o.height, o.offset_x), (Some(720), Some(540), 8));
        assert_eq!(o.trigger, Trigger::Software);
        assert_eq!(o.packet_size, Some(8192));
        assert_eq!(o.sync.as_deref(), Some("table"));
        assert_eq!(parse("genicam://first").unwrap().trigger, Trigger::Free);
        assert_eq!(
            parse("genicam://GV02?format=Mono8").unwrap().format,
            Some(PixelFormat::Mono8)
        );
    }

    #[test]
    fn rejects_bad_parameters() {
        for bad in [
            "genicam://x?bogus=1",
            "genicam://x?trigger=sometimes",
            "genicam://x?fps=-3",
            "genicam://x?trigger=software",
            "genicam://x?sync=a&fps=10",
            "genicam://x?format=yuv",
            "genicam://x?width=wide",
        ] {
            let e = parse(bad).unwrap_err();
            assert!(matches!(e, IoError::BadInput { .. }), "{bad}: {e}");
        }
    }

    #[test]
    fn format_names_round_trip() {
        for f in PixelFormat::ALL {
            assert_eq!(format_from_genicam(genicam_format_name(f)), Some(f));
        }
        assert_eq!(format_from_genicam("RGB8Packed"), Some(PixelFormat::Rgb8));
        assert_eq!(format_from_genicam("YUV422Packed"), None);
    }
}
