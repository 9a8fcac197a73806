//! Input strings (`--input ...`) and the factory that opens them.
//!
//! Forms:
//! - `DIR`, `DIR/pattern_*.png`, `images:DIR` - an image sequence
//!   (params: `format`, `fps`, `width` + `height`);
//! - `raw:FILE_OR_DIR?width=1440&height=1080&format=bayer_rggb8` - raw frames
//!   (params: `width`, `height`, `format`, `stride`, `fps`, `header`);
//! - `video:FILE`, `genicam://ID`, `sim://SCENARIO` - parsed; opened only when a builder for the
//!   scheme is compiled in or registered with [`SourceFactory::register`].
//!
//! Parameters follow `?` as `key=value` pairs joined by `&`. Unknown keys are errors.

use super::images::{ImageSequence, ImageSequenceOptions};
use super::raw::{RawOptions, RawSource};
use super::FrameSource;
use crate::IoError;
use rodtrack_core::PixelFormat;
use std::collections::BTreeMap;
use std::path::Path;
use std::str::FromStr;

/// What kind of source an input string names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InputKind {
    /// Image files (a bare path, `images:` or `file:`).
    Images,
    /// Raw frames (`raw:`).
    Raw,
    /// A video file (`video:`).
    Video,
    /// A GenICam camera (`genicam://`).
    GenICam,
    /// The simulator (`sim://`).
    Sim,
    /// Any other scheme.
    Other(String),
}

/// A parsed input string.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputSpec {
    /// The string as given.
    pub input: String,
    /// The scheme, lower case (`images` for a bare path).
    pub scheme: String,
    /// What follows the scheme (path, camera id, scenario), without the parameters.
    pub target: String,
    /// `key=value` parameters in the order given.
    pub params: Vec<(String, String)>,
}

impl InputSpec {
    /// Parses `scheme:target?k=v&k2=v2` (or `scheme://target...`, or a bare path).
    pub fn parse(input: &str) -> Result<Self, IoError> {
        let bad = |reason: &str| IoError::BadInput {
            input: input.to_string(),
            reason: reason.to_string(),
        };
        let s = input.trim();
        if s.is_empty() {
            return Err(bad("empty input"));
        }
        let (scheme, rest) = match s.find(':') {
            Some(i)
                if i >= 2
                    && s[..i].starts_with(|c: char| c.is_ascii_alphabetic())
                    && s[..i].chars().all(|c| {
                        c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.' | '_')
                    }) =>
            {
                let rest = &s[i + 1..];
                (
                    s[..i].to_ascii_lowercase(),
                    rest.strip_prefix("//").unwrap_or(rest),
                )
            }
            _ => ("images".to_string(), s),
        };
        let (target, query) = match rest.split_once('?') {
            Some((t, q)) => (t, Some(q)),
            None => (rest, None),
        };
        if target.is_empty() {
            return Err(bad(
                "nothing after the scheme (expected a path, id or scenario)",
            ));
        }
        let mut params = Vec::new();
        for pair in query.unwrap_or("").split('&').filter(|p| !p.is_empty()) {
            let Some((k, v)) = pair.split_once('=') else {
                return Err(bad(&format!("parameter `{pair}` is not key=value")));
            };
            if k.is_empty() {
                return Err(bad(&format!("parameter `{pair}` has no key")));
            }
            params.push((k.to_string(), v.to_string()));
        }
        Ok(InputSpec {
            input: input.to_string(),
            scheme,
            target: target.to_string(),
            params,
        })
    }

    /// The kind of source.
    pub fn kind(&self) -> InputKind {
        match self.scheme.as_str() {
            "images" | "file" => InputKind::Images,
            "raw" => InputKind::Raw,
            "video" => InputKind::Video,
            "genicam" => InputKind::GenICam,
            "sim" => InputKind::Sim,
            other => InputKind::Other(other.to_string()),
        }
    }

    /// The value of a parameter (the last one if repeated).
    pub fn param(&self, key: &str) -> Option<&str> {
        self.params
            .iter()
            .rev()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// A parameter parsed as `T`; an error names the input, key and value.
    pub fn param_parse<T: FromStr>(&self, key: &str) -> Result<Option<T>, IoError> {
        match self.param(key) {
            None => Ok(None),
            Some(v) => v.parse().map(Some).map_err(|_| IoError::BadInput {
                input: self.input.clone(),
                reason: format!("parameter `{key}`: cannot parse `{v}`"),
            }),
        }
    }

    /// A `format` parameter as a pixel format.
    pub fn param_format(&self) -> Result<Option<PixelFormat>, IoError> {
        match self.param("format") {
            None => Ok(None),
            Some(v) => PixelFormat::from_name(v)
                .map(Some)
                .ok_or_else(|| IoError::BadInput {
                    input: self.input.clone(),
                    reason: format!(
                        "parameter `format`: unknown pixel format `{v}` (known: {})",
                        PixelFormat::ALL.map(|f| f.name()).join(", ")
                    ),
                }),
        }
    }

    /// Fails on a parameter not in `allowed`.
    pub fn check_params(&self, allowed: &[&str]) -> Result<(), IoError> {
        match self
            .params
            .iter()
            .find(|(k, _)| !allowed.contains(&k.as_str()))
        {
            None => Ok(()),
            Some((k, _)) => Err(IoError::BadInput {
                input: self.input.clone(),
                reason: format!("unknown parameter `{k}` (allowed: {})", allowed.join(", ")),
            }),
        }
    }
}

/// Defaults from the command line or calibration, overridden by an input's own parameters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OpenOptions {
    /// Pixel format (how to read grey images; required for raw frames).
    pub format: Option<PixelFormat>,
    /// Frame rate for timestamps.
    pub fps: Option<f64>,
    /// Frame size `(width, height)` (required for raw frames).
    pub size: Option<(usize, usize)>,
}

/// Opens one scheme's sources.
pub type SourceBuilder =
    Box<dyn Fn(&InputSpec, &OpenOptions) -> Result<Box<dyn FrameSource>, IoError> + Send + Sync>;

/// Opens sources from input strings; other crates add schemes with
/// [`SourceFactory::register`] (the simulator registers `sim`).
pub struct SourceFactory {
    builders: BTreeMap<String, SourceBuilder>,
}

impl std::fmt::Debug for SourceFactory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SourceFactory")
            .field("schemes", &self.builders.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Default for SourceFactory {
    fn default() -> Self {
        Self::new()
    }
}

fn size_param(spec: &InputSpec, opts: &OpenOptions) -> Result<Option<(usize, usize)>, IoError> {
    let w: Option<usize> = spec.param_parse("width")?;
    let h: Option<usize> = spec.param_parse("height")?;
    match (w, h) {
        (Some(w), Some(h)) => Ok(Some((w, h))),
        (None, None) => Ok(opts.size),
        _ => Err(IoError::BadInput {
            input: spec.input.clone(),
            reason: "give both `width` and `height`".into(),
        }),
    }
}

fn open_images(spec: &InputSpec, opts: &OpenOptions) -> Result<Box<dyn FrameSource>, IoError> {
    spec.check_params(&["format", "fps", "width", "height"])?;
    let options = ImageSequenceOptions {
        format: spec.param_format()?.or(opts.format),
        fps: spec.param_parse("fps")?.or(opts.fps),
        size: size_param(spec, opts)?,
        ignore_sidecar: false,
    };
    Ok(Box::new(ImageSequence::open(
        Path::new(&spec.target),
        &options,
    )?))
}

fn open_raw(spec: &InputSpec, opts: &OpenOptions) -> Result<Box<dyn FrameSource>, IoError> {
    spec.check_params(&["format", "fps", "width", "height", "stride", "header"])?;
    let missing = |what: &str| IoError::BadInput {
        input: spec.input.clone(),
        reason: format!(
            "raw input needs `{what}` (e.g. raw:FILE?width=1440&height=1080&format=bayer_rggb8)"
        ),
    };
    let (width, height) = size_param(spec, opts)?.ok_or_else(|| missing("width` and `height"))?;
    let format = spec
        .param_format()?
        .or(opts.format)
        .ok_or_else(|| missing("format"))?;
    let options = RawOptions {
        width,
        height,
        format,
        stride: spec.param_parse("stride")?,
        fps: spec.param_parse("fps")?.or(opts.fps),
        header_bytes: spec.param_parse("header")?.unwrap_or(0),
    };
    Ok(Box::new(RawSource::open(Path::new(&spec.target), options)?))
}

impl SourceFactory {
    /// A factory with the built-in schemes: `images` (also `file` and bare paths) and `raw`.
    pub fn new() -> Self {
        let mut f = SourceFactory {
            builders: BTreeMap::new(),
        };
        f.register("images", Box::new(open_images));
        f.register("file", Box::new(open_images));
        f.register("raw", Box::new(open_raw));
        f
    }

    /// Adds or replaces the builder for a scheme (lower case, without `:`).
    pub fn register(&mut self, scheme: &str, builder: SourceBuilder) {
        self.builders.insert(scheme.to_ascii_lowercase(), builder);
    }

    /// The schemes that can be opened.
    pub fn schemes(&self) -> Vec<&str> {
        self.builders.keys().map(String::as_str).collect()
    }

    /// Parses and opens an input string.
    pub fn open(
        &self,
        input: &str,
        options: &OpenOptions,
    ) -> Result<Box<dyn FrameSource>, IoError> {
        let spec = InputSpec::parse(input)?;
        self.open_spec(&spec, options)
    }

    /// Opens a parsed input.
    pub fn open_spec(
        &self,
        spec: &InputSpec,
        options: &OpenOptions,
    ) -> Result<Box<dyn FrameSource>, IoError> {
        if let Some(b) = self.builders.get(&spec.scheme) {
            return b(spec, options);
        }
        match spec.kind() {
            InputKind::Other(s) => Err(IoError::BadInput {
                input: spec.input.clone(),
                reason: format!(
                    "unknown scheme `{s}` (known: {}, video, genicam, sim)",
                    self.schemes().join(", ")
                ),
            }),
            _ => Err(IoError::Unsupported {
                input: spec.input.clone(),
                scheme: spec.scheme.clone(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn parses_forms() {
        let s =
            InputSpec::parse("raw:rec/cam0.raw?width=1440&height=1080&format=bayer_rggb8").unwrap();
        assert_eq!(s.kind(), InputKind::Raw);
        assert_eq!(s.target, "rec/cam0.raw");
        assert_eq!(s.param("width"), Some("1440"));
        assert_eq!(s.param_format().unwrap(), Some(PixelFormat::BayerRggb8));
        let s = InputSpec::parse("genicam://Fake_1").unwrap();
        assert_eq!(
            (s.kind(), s.target.as_str()),
            (InputKind::GenICam, "Fake_1")
        );
        let s = InputSpec::parse("sim://two_cameras?seed=3").unwrap();
        assert_eq!(
            (s.kind(), s.target.as_str()),
            (InputKind::Sim, "two_cameras")
        );
        let s = InputSpec::parse("/data/rec 1/cam0").unwrap();
        assert_eq!(
            (s.kind(), s.target.as_str()),
            (InputKind::Images, "/data/rec 1/cam0")
        );
        let s = InputSpec::parse("C:/data").unwrap();
        assert_eq!(s.kind(), InputKind::Images);
        assert!(InputSpec::parse("raw:").is_err());
        assert!(InputSpec::parse("raw:x?width").is_err());
    }

    #[test]
    fn unsupported_and_unknown_schemes() {
        let f = SourceFactory::new();
        let o = OpenOptions::default();
        for s in ["video:a.mkv", "genicam://Fake_1", "sim://basic"] {
            let e = f.open(s, &o).unwrap_err();
            assert!(matches!(e, IoError::Unsupported { .. }), "{s}: {e}");
            assert!(e.to_string().contains("not supported in this build"));
        }
        let e = f.open("ftp://x", &o).unwrap_err();
        assert!(e.to_string().contains("unknown scheme `ftp`"), "{e}");
        let e = f.open("raw:x.raw?width=4", &o).unwrap_err();
        assert!(e.to_string().contains("height"), "{e}");
        let e = f
            .open("raw:x.raw?width=4&height=4&format=yuv", &o)
            .unwrap_err();
        assert!(e.to_string().contains("yuv"), "{e}");
        let e = f.open("images:x?colour=red", &o).unwrap_err();
        assert!(e.to_string().contains("unknown parameter `colour`"), "{e}");
    }
}
