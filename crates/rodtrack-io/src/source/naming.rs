//! File listing, frame ids from file names, glob-like patterns and the timestamps sidecar.

use crate::IoError;
use std::path::{Path, PathBuf};

/// File extensions read as images (lower case, matched case-insensitively).
pub const IMAGE_EXTENSIONS: [&str; 6] = ["png", "pgm", "ppm", "pnm", "tif", "tiff"];

/// The sidecar file with capture times, looked for in an image or raw folder.
pub const TIMESTAMPS_FILE: &str = "timestamps.csv";

/// The frame number in a file name: the last run of ASCII digits in the name without its
/// extension (`000123.png` -> 123, `cam0_frame_0042.pgm` -> 42). `None` when the stem has no
/// digit or the number does not fit in a `u64`.
pub fn parse_frame_number(path: &Path) -> Option<u64> {
    let stem = path.file_stem()?.to_str()?;
    let bytes = stem.as_bytes();
    let end = bytes.iter().rposition(|b| b.is_ascii_digit())? + 1;
    let start = bytes[..end]
        .iter()
        .rposition(|b| !b.is_ascii_digit())
        .map_or(0, |i| i + 1);
    stem[start..end].parse().ok()
}

/// Frame ids for files already sorted in name order (SPEC section 6): the number in each file
/// name when every name has one and no two names share one, else the index in name order.
/// Returns the ids, in the files' order, and whether they came from the names. When they did,
/// callers should order frames by id (`2.png` before `10.png`).
pub fn frame_ids_from_names(files: &[PathBuf]) -> (Vec<u64>, bool) {
    let numbers: Option<Vec<u64>> = files.iter().map(|p| parse_frame_number(p)).collect();
    if let Some(ids) = numbers {
        let mut sorted = ids.clone();
        sorted.sort_unstable();
        sorted.dedup();
        if sorted.len() == ids.len() {
            return (ids, true);
        }
    }
    ((0..files.len() as u64).collect(), false)
}

/// Frame ids for files in name order, with what a reader should be told: the number in each
/// file name when every name has a distinct one; when only some names have a number, the
/// numbered files only (each other file is left out, with a warning: one stray `snapshot.png`
/// must not renumber every frame); when no name has a number, or two share one, the index in
/// name order (with a warning for the shared numbers). Returns `(id, file)` in reading order
/// (by id) and the warnings.
pub fn number_frames(files: Vec<PathBuf>) -> (Vec<(u64, PathBuf)>, Vec<String>) {
    let mut warnings = Vec::new();
    let numbered: Vec<Option<u64>> = files.iter().map(|p| parse_frame_number(p)).collect();
    let count = numbered.iter().filter(|n| n.is_some()).count();
    let mut ids: Vec<u64> = numbered.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let distinct = ids.len() == count;
    if count > 0 && distinct {
        let mut out = Vec::with_capacity(count);
        for (n, path) in numbered.into_iter().zip(files) {
            match n {
                Some(id) => out.push((id, path)),
                None => warnings.push(format!(
                    "{}: no frame number in the name (the other files have one): left out",
                    path.display()
                )),
            }
        }
        out.sort_by_key(|(id, _)| *id);
        return (out, warnings);
    }
    if count > 0 {
        warnings.push(format!(
            "{} files share a frame number: frames numbered by their order in the folder",
            count - ids.len() + 1
        ));
    }
    ((0u64..).zip(files).collect(), warnings)
}

/// What a path is when it exists but is not a regular file (following symlinks): a device, a
/// FIFO, a socket, a folder. `None` for a regular file, and for a path that cannot be
/// examined (missing, dangling link: opening it reports why). Never opens the path (a FIFO
/// would block).
pub fn not_a_regular_file(path: &Path) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let meta = std::fs::metadata(path).ok()?;
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_dir() {
        Some("folder")
    } else if t.is_char_device() {
        Some("character device")
    } else if t.is_block_device() {
        Some("block device")
    } else if t.is_fifo() {
        Some("FIFO")
    } else if t.is_socket() {
        Some("socket")
    } else {
        Some("special file")
    }
}

fn has_extension(path: &Path, exts: &[&str]) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// Simple wildcard match: `*` any run of characters, `?` one character.
fn wildcard_match(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let n: Vec<char> = name.chars().collect();
    let (mut pi, mut ni) = (0usize, 0usize);
    let (mut star, mut mark) = (None::<usize>, 0usize);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    while pi < p.len() && p[pi] == '*' {
        pi += 1;
    }
    pi == p.len()
}

/// Lists the files with one of `exts` in a folder, or matching a pattern whose last component
/// holds `*` or `?` (`rec/cam0_*.png`), sorted by name. Errors: missing folder, unreadable
/// folder. An empty result is not an error here. Paths that are not regular files (after
/// following symlinks: devices such as `/dev/zero`, FIFOs, sockets) are left
/// out, each with a warning pushed to `skipped`; folders named like images are left out.
pub fn list_files_noting(
    input: &Path,
    exts: &[&str],
    skipped: &mut Vec<String>,
) -> Result<Vec<PathBuf>, IoError> {
    let name = input.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let (dir, pattern) = if name.contains('*') || name.contains('?') {
        let parent = input.parent().filter(|p| !p.as_os_str().is_empty());
        (
            parent.unwrap_or(Path::new(".")).to_path_buf(),
            Some(name.to_string()),
        )
    } else {
        (input.to_path_buf(), None)
    };
    if !dir.is_dir() {
        return Err(IoError::MissingFolder { path: dir });
    }
    let entries =
        std::fs::read_dir(&dir).map_err(|e| IoError::file(&dir, "cannot list folder", e))?;
    let mut files = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| IoError::file(&dir, "cannot list folder", e))?;
        let path = entry.path();
        if !has_extension(&path, exts) {
            continue;
        }
        if let Some(pat) = &pattern {
            let fname = entry.file_name();
            if !wildcard_match(pat, &fname.to_string_lossy()) {
                continue;
            }
        }
        if let Some(kind) = not_a_regular_file(&path) {
            if kind != "folder" {
                skipped.push(IoError::NotAFile { path, kind }.to_string());
            }
            continue;
        }
        files.push(path);
    }
    files.sort();
    Ok(files)
}

/// Lists the image files of a folder or pattern in name order (see [`IMAGE_EXTENSIONS`]).
/// This is the order in which calibration's "frame N is the N-th image" counts.
pub fn list_image_files(input: &Path) -> Result<Vec<PathBuf>, IoError> {
    list_image_files_noting(input, &mut Vec::new())
}

/// Like [`list_image_files`], with a warning in `skipped` for each path left out (see
/// [`list_files_noting`]).
pub fn list_image_files_noting(
    input: &Path,
    skipped: &mut Vec<String>,
) -> Result<Vec<PathBuf>, IoError> {
    let files = list_files_noting(input, &IMAGE_EXTENSIONS, skipped)?;
    if files.is_empty() {
        return Err(IoError::NoImages {
            path: input.to_path_buf(),
        });
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn frame_numbers_from_names() {
        assert_eq!(parse_frame_number(Path::new("000123.png")), Some(123));
        assert_eq!(
            parse_frame_number(Path::new("dir/cam0_frame_0042.pgm")),
            Some(42)
        );
        assert_eq!(parse_frame_number(Path::new("img7b.tif")), Some(7));
        assert_eq!(parse_frame_number(Path::new("image.png")), None);
        assert_eq!(
            parse_frame_number(Path::new("99999999999999999999999.png")),
            None
        );
    }

    #[test]
    fn ids_fall_back_to_index() {
        let p = |v: &[&str]| v.iter().map(PathBuf::from).collect::<Vec<_>>();
        assert_eq!(
            frame_ids_from_names(&p(&["000010.png", "000012.png"])),
            (vec![10, 12], true)
        );
        // One name without a number: all by index.
        assert_eq!(
            frame_ids_from_names(&p(&["000010.png", "last.png"])),
            (vec![0, 1], false)
        );
        // Duplicate numbers: by index.
        assert_eq!(
            frame_ids_from_names(&p(&["a1.png", "b1.png"])),
            (vec![0, 1], false)
        );
    }

    #[test]
    fn wildcards() {
        assert!(wildcard_match("cam0_*.png", "cam0_0001.png"));
        assert!(!wildcard_match("cam0_*.png", "cam1_0001.png"));
        assert!(wildcard_match("f??.pgm", "f01.pgm"));
        assert!(!wildcard_match("f??.pgm", "f001.pgm"));
        assert!(wildcard_match("*", "x"));
    }
}
