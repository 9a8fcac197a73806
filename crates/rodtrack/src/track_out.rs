//! `rodtrack track`'s outputs: the sinks opened before any file is truncated, `--out` checked
//! against the run's inputs, broken pipes recognised.

use anyhow::{bail, Result};
use rodtrack_io::{CsvSink, JsonlSink, MultiSink, UdpSink};

/// Opens the file sink (`-`: standard output) and the UDP sink. The UDP address is checked
/// (and its socket opened) first: the output file is created, truncating an existing one,
/// only when every other sink is open.
pub fn open_sinks(
    out: &std::path::Path,
    format: Option<&str>,
    udp: Option<&str>,
) -> Result<MultiSink> {
    let jsonl = match format {
        Some(f) => f == "jsonl",
        None => out.extension().is_some_and(|e| e == "jsonl" || e == "json"),
    };
    let udp = udp.map(UdpSink::new).transpose()?;
    let mut sink = MultiSink::new();
    if out.as_os_str() == "-" {
        let stdout = std::io::stdout();
        if jsonl {
            sink.push(Box::new(JsonlSink::new(stdout, "standard output")));
        } else {
            sink.push(Box::new(CsvSink::new(stdout, "standard output")?));
        }
    } else if jsonl {
        sink.push(Box::new(JsonlSink::create(out)?));
    } else {
        sink.push(Box::new(CsvSink::create(out)?));
    }
    if let Some(u) = udp {
        sink.push(Box::new(u));
    }
    Ok(sink)
}

/// Refuses an output path that is one of the run's own input files (the calibration, ...):
/// it would be truncated before being read.
pub fn check_out_is_not_an_input(out: &std::path::Path, inputs: &[&std::path::Path]) -> Result<()> {
    if out.as_os_str() == "-" {
        return Ok(());
    }
    let Ok(o) = out.canonicalize() else {
        return Ok(()); // Does not exist yet: not an input.
    };
    for i in inputs {
        if i.canonicalize().is_ok_and(|c| c == o) {
            bail!(
                "--out {} is the input file {}: refusing to overwrite it",
                out.display(),
                i.display()
            );
        }
    }
    Ok(())
}

/// True when `e` is a write to a pipe whose reader has gone.
pub fn is_broken_pipe(e: &rodtrack_io::IoError) -> bool {
    let mut cur: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(err) = cur {
        if let Some(io) = err.downcast_ref::<std::io::Error>() {
            if io.kind() == std::io::ErrorKind::BrokenPipe {
                return true;
            }
        }
        cur = err.source();
    }
    false
}
