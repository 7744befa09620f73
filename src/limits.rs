//! The limits every reader enforces, in one place, and the checks that apply them before
//! the work starts.
//!
//! A file musculo reads must be a regular file (a device such as `/dev/zero` would be read
//! forever, a named pipe would block until something writes into it) of at most
//! [`MAX_TEXT_FILE_BYTES`] (text formats: models, setups, `.mot`/`.sto`, `.trc`, `.bvh`) or
//! [`MAX_BINARY_FILE_BYTES`] (`.c3d`, `.npy`, `.npz`). Inside a file:
//!
//! | what                                   | limit                              |
//! |----------------------------------------|------------------------------------|
//! | members of an `.npz` archive           | [`MAX_NPZ_MEMBERS`]                |
//! | bytes of an `.npz` archive, inflated   | [`MAX_NPZ_INFLATED_BYTES`] (all members together) |
//! | attributes of one XML element          | [`MAX_XML_ATTRIBUTES`]             |
//! | nesting depth of a model's XML elements | [`MAX_XML_DEPTH`]                 |
//! | bodies of a model                      | [`MAX_BODIES`]                     |
//! | joints and end sites of a BVH file     | [`MAX_BVH_JOINTS`]                 |
//! | nesting depth of a BVH hierarchy       | [`MAX_BVH_DEPTH`]                  |
//!
//! Each is checked before the work it bounds: the size from the file's metadata before it
//! is opened, an archive member's inflated size from the archive's directory before it is
//! inflated (and again while it is, as the directory may lie), XML attributes by a linear
//! scan before the document is parsed, a model's nesting depth and bodies after parsing
//! (linear) and before the model is read. A file over a limit is refused with an
//! [`Error::Limit`] naming the file, where in it, the limit and this module's constant.
//! The limits are far above what motion-capture and OpenSim files hold (the full-body model
//! has 23 bodies, a long mocap trial a few hundred megabytes); they exist so that a
//! damaged or hostile file is refused in seconds and bounded memory.

use crate::error::Error;
use std::io::Read;
use std::path::Path;

const MIB: u64 = 1 << 20;

/// Largest text file read (models, setups, `.mot`/`.sto`, `.trc`, `.bvh`, maps): 1 GiB.
pub const MAX_TEXT_FILE_BYTES: u64 = 1024 * MIB;
/// Largest binary file read (`.c3d`, `.npy`, `.npz`): 2 GiB.
pub const MAX_BINARY_FILE_BYTES: u64 = 2048 * MIB;
/// Most members in one `.npz` archive.
pub const MAX_NPZ_MEMBERS: usize = 4096;
/// Most bytes an `.npz` archive's members inflate to, all together: 1 GiB.
pub const MAX_NPZ_INFLATED_BYTES: u64 = 1024 * MIB;
/// Most attributes on one XML element (OpenSim writes at most a few).
pub const MAX_XML_ATTRIBUTES: usize = 64;
/// Deepest nesting of a model's XML elements (OpenSim models nest about 12 deep).
pub const MAX_XML_DEPTH: usize = 256;
/// Most bodies in a model (ground included).
pub const MAX_BODIES: usize = 10_000;
/// Most joints and end sites in a BVH hierarchy.
pub const MAX_BVH_JOINTS: usize = 10_000;
/// Deepest nesting of a BVH hierarchy (human skeletons are about 10 deep).
pub const MAX_BVH_DEPTH: usize = 1_000;

/// A refusal: `file` at `location` is over `what`'s limit.
pub(crate) fn exceeded(file: &str, location: &str, message: String) -> Error {
    Error::Limit {
        file: file.to_string(),
        location: location.to_string(),
        message,
    }
}

/// Checks that `path` is a regular file (links followed) of at most `max_bytes`; returns its
/// size. Nothing is opened: a named pipe is refused before a read could block on it.
pub fn check_regular_file(path: &Path, max_bytes: u64, limit_name: &str) -> crate::Result<u64> {
    let meta = std::fs::metadata(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file = path.display().to_string();
    if meta.is_dir() {
        return Err(exceeded(
            &file,
            "file",
            "is a folder, not a file".to_string(),
        ));
    }
    if !meta.is_file() {
        return Err(exceeded(
            &file,
            "file",
            "is a device, named pipe or socket, not a regular file: musculo reads regular \
             files only (a device or pipe could be read forever or block)"
                .to_string(),
        ));
    }
    if meta.len() > max_bytes {
        return Err(exceeded(
            &file,
            "file",
            format!(
                "is {} bytes, more than the {} bytes musculo reads from such a file \
                 (musculo::limits::{limit_name})",
                meta.len(),
                max_bytes
            ),
        ));
    }
    Ok(meta.len())
}

/// Reads the regular file at `path` whole, refusing one over `max_bytes` before reading
/// (and one that grows past it while being read).
pub fn read_regular_file(path: &Path, max_bytes: u64, limit_name: &str) -> crate::Result<Vec<u8>> {
    let size = check_regular_file(path, max_bytes, limit_name)?;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(exceeded(
            &path.display().to_string(),
            "file",
            format!("grew past {max_bytes} bytes while being read (musculo::limits::{limit_name})"),
        ));
    }
    Ok(bytes)
}

/// Reads a text-format file's bytes ([`MAX_TEXT_FILE_BYTES`]).
pub fn read_text_file_bytes(path: &Path) -> crate::Result<Vec<u8>> {
    read_regular_file(path, MAX_TEXT_FILE_BYTES, "MAX_TEXT_FILE_BYTES")
}

/// Reads a binary-format file's bytes ([`MAX_BINARY_FILE_BYTES`]).
pub fn read_binary_file_bytes(path: &Path) -> crate::Result<Vec<u8>> {
    read_regular_file(path, MAX_BINARY_FILE_BYTES, "MAX_BINARY_FILE_BYTES")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_folders_are_refused_without_reading() {
        #[cfg(unix)]
        {
            let e = read_text_file_bytes(Path::new("/dev/zero")).unwrap_err();
            assert!(matches!(e, Error::Limit { .. }), "{e}");
            assert!(e.to_string().contains("not a regular file"), "{e}");
        }
        let e = read_text_file_bytes(&std::env::temp_dir()).unwrap_err();
        assert!(e.to_string().contains("folder"), "{e}");
    }

    #[test]
    fn a_file_over_the_limit_is_refused_naming_the_limit() {
        let p = std::env::temp_dir().join(format!("musculo-limits-{}", std::process::id()));
        std::fs::write(&p, b"0123456789").unwrap();
        let e = read_regular_file(&p, 9, "TEST_LIMIT")
            .unwrap_err()
            .to_string();
        assert!(e.contains("10 bytes") && e.contains("TEST_LIMIT"), "{e}");
        assert_eq!(
            read_regular_file(&p, 10, "TEST_LIMIT").unwrap(),
            b"0123456789"
        );
        let _ = std::fs::remove_file(&p);
    }
}
