//! NumPy `.npy` and `.npz` files: reading float arrays of any shape and writing them
//! atomically, through the `ndarray-npy` crate (the format itself is never parsed by hand
//! here).
//!
//! Reading is defensive: the whole file is read, and the array is first *viewed* in place
//! (`ViewNpyExt`), which checks the header's shape against the bytes actually present before
//! anything is allocated — so a corrupted header that claims 10¹⁵ elements is an error, not
//! an allocation failure. Only little-endian `float32` (`<f4`) and `float64` (`<f8`) data are
//! read (what NumPy writes on every common platform); C and Fortran order are both accepted
//! and returned in standard (C) layout. `.npz` archives are opened with the `zip` crate and
//! each member goes through the same `.npy` path.
//!
//! Writing goes through [`crate::io::output`]: a temporary file in the destination's folder,
//! flushed, synced and then renamed over the destination, so an interrupted run leaves
//! either the old file or the new one, never half of one.
//!
//! Errors: a file that cannot be read or written is [`Error::Io`]; a file that is not an
//! `.npy`, or holds another dtype or rank, is [`Error::Motion`] naming the file (and the
//! archive member for `.npz`).

use crate::error::Error;
use crate::io::output::AtomicFile;
pub use crate::io::output::{abandoned_temporary_target, is_temporary_name, write_file_atomic};
use ndarray::{ArrayD, ArrayViewD, Dimension};
use ndarray_npy::{
    NpzWriter, ReadNpyExt, ReadableElement, ViewElement, ViewNpyError, ViewNpyExt, WritableElement,
    WriteNpyExt,
};
use std::io::Read;
use std::path::Path;

/// The float element types musculo reads and writes (`f32`, `f64`).
pub trait NpyFloat:
    ReadableElement + WritableElement + ViewElement + Copy + Into<f64> + 'static
{
    /// NumPy's type descriptor for the little-endian type (`<f4`, `<f8`).
    const DESCR: &'static str;
}

impl NpyFloat for f32 {
    const DESCR: &'static str = "<f4";
}

impl NpyFloat for f64 {
    const DESCR: &'static str = "<f8";
}

fn motion_error(source: &str, location: &str, message: impl Into<String>) -> Error {
    Error::Motion {
        file: source.to_string(),
        location: location.to_string(),
        message: message.into(),
    }
}

fn io_error(path: &Path, source: std::io::Error) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// `(170, 22, 3)`, as NumPy prints a shape.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Refuses a header length field larger than the file before the crate allocates a buffer
/// for it (`.npy` versions 2 and 3 store it as a 32-bit number, up to 4 GiB).
fn check_header_length(bytes: &[u8], source: &str) -> crate::Result<()> {
    // Layout: magic (6 bytes) · major, minor (2) · HEADER_LEN (u16 for v1, u32 for v2/v3).
    if bytes.len() >= 12 && bytes.starts_with(b"\x93NUMPY") && bytes[6] >= 2 {
        let len = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
        if len > bytes.len() {
            return Err(motion_error(
                source,
                "header",
                format!(
                    "header length {len} exceeds the file size ({} bytes): truncated or not an .npy file",
                    bytes.len()
                ),
            ));
        }
    }
    Ok(())
}

fn view_error(e: ViewNpyError, source: &str, want: &str) -> Error {
    let message = match e {
        ViewNpyError::Io(e) => format!("not a complete .npy file ({e})"),
        ViewNpyError::ParseHeader(e) => format!("not an .npy file: {e}"),
        ViewNpyError::WrongDescriptor(d) => format!("dtype {d} where {want} is expected"),
        ViewNpyError::NonNativeEndian => format!(
            "big-endian data where little-endian {want} is expected (re-save it with NumPy's \
             default byte order)"
        ),
        ViewNpyError::MissingBytes(n) => {
            format!("truncated: {n} bytes of the array described in the header are missing")
        }
        ViewNpyError::ExtraBytes(n) => {
            format!("{n} bytes beyond the array described in the header")
        }
        ViewNpyError::LengthOverflow => "the header's shape overflows the address space".into(),
        e => e.to_string(),
    };
    motion_error(source, "header", message)
}

/// Views the array in place (which checks the header against the bytes present), then copies
/// it out in standard layout.
fn parse_as<A: NpyFloat>(bytes: &[u8]) -> Result<ArrayD<A>, ViewNpyError> {
    match ArrayViewD::<A>::view_npy(bytes) {
        Ok(view) => Ok(view.as_standard_layout().into_owned()),
        // The length was checked before the alignment, so the crate's reader, which allocates
        // what the header says, allocates no more than the file holds.
        Err(ViewNpyError::MisalignedData) => ArrayD::<A>::read_npy(bytes)
            .map(|a| a.as_standard_layout().into_owned())
            .map_err(|e| ViewNpyError::InvalidData(e.to_string().into())),
        Err(e) => Err(e),
    }
}

/// Parses the bytes of an `.npy` file holding little-endian `A` (`f32` or `f64`) data, of
/// any rank. `source` names the file in errors.
pub fn parse_array<A: NpyFloat>(bytes: &[u8], source: &str) -> crate::Result<ArrayD<A>> {
    check_header_length(bytes, source)?;
    let want = if A::DESCR == "<f4" {
        "float32 ('<f4')"
    } else {
        "float64 ('<f8')"
    };
    parse_as::<A>(bytes).map_err(|e| view_error(e, source, want))
}

/// Parses an `.npy` file of `float32` or `float64` data, widened to `f64` (exactly).
pub fn parse_array_as_f64(bytes: &[u8], source: &str) -> crate::Result<ArrayD<f64>> {
    check_header_length(bytes, source)?;
    let want = "float32 ('<f4') or float64 ('<f8')";
    match parse_as::<f64>(bytes) {
        Err(ViewNpyError::WrongDescriptor(_)) => parse_as::<f32>(bytes)
            .map(|a| a.mapv(f64::from))
            .map_err(|e| view_error(e, source, want)),
        r => r.map_err(|e| view_error(e, source, want)),
    }
}

fn read_bytes(path: &Path) -> crate::Result<Vec<u8>> {
    crate::limits::read_binary_file_bytes(path)
}

/// Reads an `.npy` file of little-endian `A` (`f32` or `f64`) data of any rank.
pub fn read_array<A: NpyFloat>(path: &Path) -> crate::Result<ArrayD<A>> {
    parse_array(&read_bytes(path)?, &path.display().to_string())
}

/// Reads an `.npy` file of `float32` data of any rank.
pub fn read_array_f32(path: &Path) -> crate::Result<ArrayD<f32>> {
    read_array(path)
}

/// Reads an `.npy` file of `float64` data of any rank.
pub fn read_array_f64(path: &Path) -> crate::Result<ArrayD<f64>> {
    read_array(path)
}

/// Reads an `.npy` file of `float32` or `float64` data, widened to `f64` (exactly).
pub fn read_array_as_f64(path: &Path) -> crate::Result<ArrayD<f64>> {
    parse_array_as_f64(&read_bytes(path)?, &path.display().to_string())
}

/// Checks an array's rank, naming its shape in the error.
pub fn expect_rank<'a, A, D: Dimension>(
    array: ArrayViewD<'a, A>,
    source: &str,
) -> crate::Result<ndarray::ArrayView<'a, A, D>> {
    let shape = array.shape().to_vec();
    array.into_dimensionality::<D>().map_err(|_| {
        motion_error(
            source,
            "array shape",
            format!(
                "shape {} has rank {} where rank {} is expected",
                shape_text(&shape),
                shape.len(),
                D::NDIM.map_or("any".to_string(), |n| n.to_string())
            ),
        )
    })
}

/// An `.npz` file opened as a zip archive, with the file's name for messages.
/// A regular file within [`crate::limits::MAX_BINARY_FILE_BYTES`] of at most
/// [`crate::limits::MAX_NPZ_MEMBERS`] members (else [`Error::Limit`]).
fn open_npz(path: &Path) -> crate::Result<(String, NpzArchive)> {
    use crate::limits::{MAX_BINARY_FILE_BYTES, MAX_NPZ_MEMBERS, check_regular_file};
    check_regular_file(path, MAX_BINARY_FILE_BYTES, "MAX_BINARY_FILE_BYTES")?;
    let source = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| io_error(path, e))?;
    let zip = zip::ZipArchive::new(std::io::BufReader::new(file)).map_err(|e| {
        motion_error(
            &source,
            "archive",
            format!("not an .npz (zip) archive: {e}"),
        )
    })?;
    if zip.len() > MAX_NPZ_MEMBERS {
        return Err(crate::limits::exceeded(
            &source,
            "archive",
            format!(
                "{} members, more than {MAX_NPZ_MEMBERS} (musculo::limits::MAX_NPZ_MEMBERS)",
                zip.len()
            ),
        ));
    }
    Ok((source, zip))
}

type NpzArchive = zip::ZipArchive<std::io::BufReader<std::fs::File>>;

/// The bytes of archive member `member` into `bytes` (cleared first). `inflated` counts
/// the bytes the archive's members have inflated to so far: the member's size as the
/// archive's directory gives it is checked against what is left of
/// [`crate::limits::MAX_NPZ_INFLATED_BYTES`] before it is inflated, and inflating stops one
/// byte past that size (a directory may understate it).
fn read_member(
    member: &mut zip::read::ZipFile<'_, impl Read>,
    source: &str,
    inflated: &mut u64,
    bytes: &mut Vec<u8>,
) -> crate::Result<()> {
    use crate::limits::MAX_NPZ_INFLATED_BYTES;
    let name = member.name().to_string();
    let location = format!("archive member \"{name}\"");
    let declared = member.size();
    if declared > MAX_NPZ_INFLATED_BYTES - *inflated {
        return Err(crate::limits::exceeded(
            source,
            &location,
            format!(
                "inflates to {declared} bytes, which with the members before it is more than \
                 the {MAX_NPZ_INFLATED_BYTES} bytes musculo inflates from one archive \
                 (musculo::limits::MAX_NPZ_INFLATED_BYTES)"
            ),
        ));
    }
    bytes.clear();
    bytes.reserve(usize::try_from(declared).unwrap_or(0));
    member
        .take(declared + 1)
        .read_to_end(bytes)
        .map_err(|e| motion_error(source, &location, e.to_string()))?;
    if bytes.len() as u64 > declared {
        return Err(motion_error(
            source,
            &location,
            format!("inflates past the {declared} bytes the archive's directory gives it"),
        ));
    }
    *inflated += declared;
    Ok(())
}

/// Every member of an `.npz` archive (NumPy's `savez`/`savez_compressed`), in archive order,
/// named without the `.npy` suffix, each parsed with `parse` (e.g. [`parse_array::<f32>`]).
fn read_npz_with<T>(
    path: &Path,
    parse: impl Fn(&[u8], &str) -> crate::Result<T>,
) -> crate::Result<Vec<(String, T)>> {
    let (source, mut zip) = open_npz(path)?;
    let mut out = Vec::with_capacity(zip.len().min(1024));
    let mut bytes = Vec::new();
    let mut inflated = 0;
    for i in 0..zip.len() {
        let mut member = zip
            .by_index(i)
            .map_err(|e| motion_error(&source, &format!("archive member {i}"), e.to_string()))?;
        let name = member.name().to_string();
        read_member(&mut member, &source, &mut inflated, &mut bytes)?;
        if is_text(&bytes) {
            continue;
        }
        let key = name.strip_suffix(".npy").unwrap_or(&name).to_string();
        let array = parse(&bytes, &format!("{source} [{name}]"))?;
        out.push((key, array));
    }
    Ok(out)
}

/// Whether the `.npy` bytes hold a text member (a 1-D `uint8` array, see [`write_npz_with_texts`]).
fn is_text(bytes: &[u8]) -> bool {
    ndarray::ArrayView1::<u8>::view_npy(bytes).is_ok()
}

/// The text member `name` of an `.npz` archive ([`write_npz_with_texts`]), None when the
/// archive has no member of that name; an error when it is not UTF-8 bytes.
pub fn read_npz_text(path: &Path, name: &str) -> crate::Result<Option<String>> {
    let (source, mut zip) = open_npz(path)?;
    let member_name = format!("{name}.npy");
    let mut member = match zip.by_name(&member_name) {
        Ok(m) => m,
        Err(zip::result::ZipError::FileNotFound) => return Ok(None),
        Err(e) => {
            return Err(motion_error(
                &source,
                &format!("archive member \"{member_name}\""),
                e.to_string(),
            ));
        }
    };
    let mut bytes = Vec::new();
    read_member(&mut member, &source, &mut 0, &mut bytes)?;
    let location = format!("archive member \"{member_name}\"");
    let text = ndarray::ArrayView1::<u8>::view_npy(&bytes)
        .map_err(|e| view_error(e, &source, "uint8 ('|u1') text"))?;
    String::from_utf8(text.to_vec())
        .map(Some)
        .map_err(|e| motion_error(&source, &location, format!("not UTF-8 text: {e}")))
}

/// Reads every array of an `.npz` archive holding little-endian `A` data.
pub fn read_npz<A: NpyFloat>(path: &Path) -> crate::Result<Vec<(String, ArrayD<A>)>> {
    read_npz_with(path, parse_array::<A>)
}

/// Reads every array of an `.npz` archive of `float32` data.
pub fn read_npz_f32(path: &Path) -> crate::Result<Vec<(String, ArrayD<f32>)>> {
    read_npz(path)
}

/// Reads every array of an `.npz` archive of `float32` or `float64` data, widened to `f64`.
pub fn read_npz_as_f64(path: &Path) -> crate::Result<Vec<(String, ArrayD<f64>)>> {
    read_npz_with(path, parse_array_as_f64)
}

/// The members of an `.npz` archive in archive order, named without the `.npy` suffix, with
/// the arrays of the members named in `wanted` parsed (float32 or float64, widened to f64);
/// the others are listed from the archive's directory, not read — a cheap check that a file
/// is the archive it should be.
pub fn read_npz_some_as_f64(
    path: &Path,
    wanted: &[&str],
) -> crate::Result<Vec<(String, Option<ArrayD<f64>>)>> {
    let (source, mut zip) = open_npz(path)?;
    let mut out = Vec::with_capacity(zip.len().min(1024));
    let mut inflated = 0;
    for i in 0..zip.len() {
        let mut member = zip
            .by_index(i)
            .map_err(|e| motion_error(&source, &format!("archive member {i}"), e.to_string()))?;
        let name = member.name().to_string();
        let key = name.strip_suffix(".npy").unwrap_or(&name).to_string();
        let array = if wanted.contains(&key.as_str()) {
            let mut bytes = Vec::new();
            read_member(&mut member, &source, &mut inflated, &mut bytes)?;
            Some(parse_array_as_f64(&bytes, &format!("{source} [{name}]"))?)
        } else {
            None
        };
        out.push((key, array));
    }
    Ok(out)
}

fn write_error(path: &Path, e: impl std::fmt::Display) -> Error {
    io_error(path, std::io::Error::other(e.to_string()))
}

/// Writes `array` as an `.npy` file (little-endian, C order), atomically.
pub fn write_npy<A: NpyFloat>(path: &Path, array: ArrayViewD<'_, A>) -> crate::Result<()> {
    let (atomic, file) = AtomicFile::create(path)?;
    let mut writer = std::io::BufWriter::new(file);
    array
        .as_standard_layout()
        .write_npy(&mut writer)
        .map_err(|e| write_error(path, e))?;
    let file = writer
        .into_inner()
        .map_err(|e| write_error(path, e.error()))?;
    atomic.commit(file)
}

/// Writes named arrays as an `.npz` archive (NumPy's `savez`, or `savez_compressed` with
/// `compressed`), atomically; `np.load(path)[name]` gives each array back.
pub fn write_npz<A: NpyFloat>(
    path: &Path,
    arrays: &[(&str, ArrayViewD<'_, A>)],
    compressed: bool,
) -> crate::Result<()> {
    write_npz_with_texts(path, arrays, &[], compressed)
}

/// [`write_npz`] with text members: each (name, text) is stored as a 1-D `uint8` array of
/// the text's UTF-8 bytes (`bytes(np.load(path)[name]).decode()` gives it back). The readers
/// of float arrays here leave text members out; [`read_npz_text`] reads one.
pub fn write_npz_with_texts<A: NpyFloat>(
    path: &Path,
    arrays: &[(&str, ArrayViewD<'_, A>)],
    texts: &[(&str, &str)],
    compressed: bool,
) -> crate::Result<()> {
    let bytes = npz_bytes(arrays, texts, compressed)?;
    write_file_atomic(path, &bytes)
}

/// The bytes of the `.npz` archive [`write_npz_with_texts`] writes, for a caller that writes
/// them itself (with other files, in an [`crate::io::output::OutputSet`]). The archive is
/// assembled in memory: writing it cannot fail half-way, so the zip writer never reports a
/// failure of its own (it printed `ZipWriter drop failed` on a full disk); the file's write
/// errors come once, from the file.
pub fn npz_bytes<A: NpyFloat>(
    arrays: &[(&str, ArrayViewD<'_, A>)],
    texts: &[(&str, &str)],
    compressed: bool,
) -> crate::Result<Vec<u8>> {
    let names: Vec<&str> = (arrays.iter().map(|(n, _)| *n))
        .chain(texts.iter().map(|(n, _)| *n))
        .collect();
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() || names[..i].contains(name) {
            return Err(Error::invalid(
                "arrays",
                format!("array names must be unique and non-empty (\"{name}\")"),
            ));
        }
    }
    let bad = |e: &dyn std::fmt::Display| Error::invalid("arrays", e.to_string());
    let writer = std::io::Cursor::new(Vec::new());
    let mut npz = if compressed {
        NpzWriter::new_compressed(writer)
    } else {
        NpzWriter::new(writer)
    };
    for (name, array) in arrays {
        npz.add_array(*name, &array.as_standard_layout())
            .map_err(|e| bad(&e))?;
    }
    for (name, text) in texts {
        npz.add_array(*name, &ndarray::ArrayView1::from(text.as_bytes()))
            .map_err(|e| bad(&e))?;
    }
    Ok(npz.finish().map_err(|e| bad(&e))?.into_inner())
}

/// Writes one `f32` array as `.npy` (see [`write_npy`]).
pub fn write_npy_f32(path: &Path, array: ArrayViewD<'_, f32>) -> crate::Result<()> {
    write_npy(path, array)
}
