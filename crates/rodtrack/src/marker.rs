//! `rodtrack marker`: the printable marker (SVG or PDF at exact physical size).

use anyhow::{bail, Context, Result};
use rodtrack_core::{Marker, MarkerSpec};
use rodtrack_print::{PageSize, PrintOptions};
use std::path::{Path, PathBuf};

/// Arguments of `rodtrack marker`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output file, `.svg` or `.pdf` (the format follows the extension). An SVG holds one page:
    /// when the markers need more, pages 2, 3, ... go to `NAME-2.svg`, `NAME-3.svg`, ...
    #[arg(long)]
    pub out: PathBuf,
    /// Rod ids to print, one marker each (`--rod 0 1 2` or `--rod 0 --rod 1`); default 0, or
    /// every rod of a calibration-inputs file given with `--marker`.
    #[arg(long = "rod", num_args = 1..)]
    pub rods: Vec<u32>,
    /// Marker description (JSON, the `marker` object of the calibration inputs), or a whole
    /// calibration-inputs file (each rod's own marker); default marker v1.
    #[arg(long)]
    pub marker: Option<PathBuf>,
    /// Rod diameter, mm (overrides the description's `rod_diameter_mm`).
    #[arg(long, allow_negative_numbers = true)]
    pub diameter_mm: Option<f64>,
    /// Width of the glue strip, mm (0 for none).
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub glue_mm: f64,
    /// Page: `a4`, `letter` (further pages when needed) or `fit` (one page just big enough).
    #[arg(long, default_value = "a4", value_parser = ["a4", "letter", "fit"])]
    pub page: String,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let ext = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let is_pdf = match ext.as_deref() {
        Some("pdf") => true,
        Some("svg") => false,
        _ => bail!(
            "{}: the output must end in .svg or .pdf",
            args.out.display()
        ),
    };
    let (mut specs, per_rod) = match &args.marker {
        None => (vec![(0, MarkerSpec::default())], false),
        Some(path) => read_markers(path)?,
    };
    if !args.rods.is_empty() {
        specs = if per_rod {
            let mut picked = Vec::new();
            for rod in &args.rods {
                match specs.iter().find(|(r, _)| r == rod) {
                    Some((_, s)) => picked.push((*rod, s.clone())),
                    None => bail!(
                        "rod {rod} is not in {}",
                        args.marker.as_deref().unwrap_or(Path::new("")).display()
                    ),
                }
            }
            picked
        } else {
            let spec = specs[0].1.clone();
            args.rods.iter().map(|r| (*r, spec.clone())).collect()
        };
    }
    if let Some(d) = args.diameter_mm {
        for (_, s) in &mut specs {
            s.rod_diameter_mm = d;
        }
    }
    let markers: Vec<(u32, Marker)> = specs
        .iter()
        .map(|(rod, s)| {
            s.validate()
                .map(|m| (*rod, m))
                .with_context(|| format!("marker of rod {rod}"))
        })
        .collect::<Result<_>>()?;
    let refs: Vec<(u32, &Marker)> = markers.iter().map(|(r, m)| (*r, m)).collect();
    let opts = PrintOptions {
        glue_mm: args.glue_mm,
        page: match args.page.as_str() {
            "letter" => PageSize::Letter,
            "fit" => PageSize::Fit,
            _ => PageSize::A4,
        },
    };
    let pages = rodtrack_print::layout(&refs, &opts)?;
    let (w, h) = (pages[0].width_mm, pages[0].height_mm);
    let mut written = Vec::new();
    if is_pdf {
        let bytes = rodtrack_print::pdf(&refs, &opts)?;
        write(&args.out, &bytes)?;
        written.push(args.out.clone());
    } else {
        for (i, doc) in rodtrack_print::svg_pages(&refs, &opts)?.iter().enumerate() {
            let path = if i == 0 {
                args.out.clone()
            } else {
                numbered(&args.out, i + 1)
            };
            write(&path, doc.as_bytes())?;
            written.push(path);
        }
    }
    let rods: Vec<String> = refs.iter().map(|(r, _)| r.to_string()).collect();
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    println!(
        "wrote {} (rods {}; {} page(s) of {w:.1} x {h:.1} mm): {}",
        names.join(", "),
        rods.join(", "),
        pages.len(),
        rodtrack_print::PRINT_AT_100
    );
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("{}: cannot write", path.display()))
}

/// `dir/name.svg` -> `dir/name-N.svg`.
fn numbered(path: &Path, n: usize) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{stem}-{n}.svg"))
}

/// A marker description (as rod 0), or every rod's marker of a calibration-inputs file; true
/// for the latter.
fn read_markers(path: &Path) -> Result<(Vec<(u32, MarkerSpec)>, bool)> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not valid JSON", path.display()))?;
    let Some(rods) = value.get("rods") else {
        let spec: MarkerSpec = rodtrack_sdk::calibration::from_json_warning_unknown(
            value,
            path,
            &mut rodtrack_sdk::print_warning,
        )
        .with_context(|| format!("{}: not a marker description", path.display()))?;
        return Ok((vec![(0, spec)], false));
    };
    let Some(rods) = rods.as_array() else {
        bail!("{}: rods: must be a list", path.display());
    };
    let mut out = Vec::new();
    for (i, r) in rods.iter().enumerate() {
        let rod = r
            .get("rod")
            .and_then(|v| v.as_u64())
            .and_then(|v| u32::try_from(v).ok())
            .with_context(|| {
                format!("{}: rods[{i}].rod: missing or not a rod id", path.display())
            })?;
        let spec = match r.get("marker") {
            None => MarkerSpec::default(),
            Some(m) => rodtrack_sdk::calibration::from_json_warning_unknown(
                m.clone(),
                path,
                &mut rodtrack_sdk::print_warning,
            )
            .with_context(|| format!("{}: rods[{i}].marker", path.display()))?,
        };
        out.push((rod, spec));
    }
    if out.is_empty() {
        bail!("{}: rods: empty", path.display());
    }
    Ok((out, true))
}
