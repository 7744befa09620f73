//! Reading text files: every reader of a text format (models, force sets, motions, loads,
//! setups, marker files) reads its file through [`read_text`], so a file that is not UTF-8
//! is refused with the line, column and byte offset of the first byte that is not, instead
//! of the operating system's "stream did not contain valid UTF-8".

use crate::error::Error;
use std::path::Path;

/// Reads the file at `path` as UTF-8 text. Errors: [`Error::Io`] when it cannot be read,
/// [`Error::Encoding`] when it is not UTF-8.
///
/// The file must be a regular file within [`crate::limits::MAX_TEXT_FILE_BYTES`] (else
/// [`Error::Limit`], before anything is read). A UTF-8 byte-order mark at its start (some
/// Windows editors write one) is dropped, for every text format alike.
pub fn read_text(path: &Path) -> crate::Result<String> {
    let bytes = crate::limits::read_text_file_bytes(path)?;
    text_from_bytes(bytes, &path.display().to_string())
}

/// The UTF-8 byte-order mark, `U+FEFF` encoded.
const UTF8_BOM: &[u8] = &[0xEF, 0xBB, 0xBF];

/// `bytes` as UTF-8 text without a leading UTF-8 byte-order mark; `source` names the file
/// in the [`Error::Encoding`] for bytes that are not UTF-8 (its offset counts from the start
/// of the file, mark included).
pub fn text_from_bytes(mut bytes: Vec<u8>, source: &str) -> crate::Result<String> {
    let skipped = if bytes.starts_with(UTF8_BOM) {
        bytes.drain(..UTF8_BOM.len());
        UTF8_BOM.len()
    } else {
        0
    };
    String::from_utf8(bytes).map_err(|e| {
        let bytes = e.as_bytes();
        let offset = e.utf8_error().valid_up_to();
        // The prefix is valid UTF-8, so lines and characters can be counted in it.
        let before = std::str::from_utf8(&bytes[..offset]).unwrap_or("");
        let (line, column) = crate::xml::line_column(before, before.len());
        let byte = bytes[offset];
        let hint = if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
            "the file starts with a UTF-16 byte-order mark: save it as UTF-8"
        } else {
            "save the file as UTF-8 (a byte like this is often a letter of a Windows or \
             Latin-1 code page)"
        };
        Error::Encoding {
            file: source.to_string(),
            line,
            column,
            offset: offset + skipped,
            message: format!("byte 0x{byte:02X} is not UTF-8 text; {hint}"),
        }
    })
}

/// A number for a message: as Rust prints it, but in exponent form when that would be
/// long (1e250 rather than 251 digits).
pub fn short_number(v: f64) -> String {
    if v.is_finite() && v != 0.0 && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_bad_byte_is_located_by_line_column_and_offset() {
        let mut bytes = b"time\tq\n0\t1\n".to_vec();
        bytes.extend_from_slice("0.01\tè".as_bytes());
        bytes.push(0xE9); // Latin-1 é
        bytes.extend_from_slice(b"\n");
        match text_from_bytes(bytes, "m.sto") {
            Err(e @ Error::Encoding { .. }) => {
                let Error::Encoding {
                    line,
                    column,
                    offset,
                    ref message,
                    ..
                } = e
                else {
                    unreachable!()
                };
                assert_eq!((line, column, offset), (3, 7, 18));
                assert!(message.contains("0xE9"), "{message}");
                assert!(
                    e.to_string().starts_with("m.sto:3:7: byte offset 18:"),
                    "{e}"
                );
            }
            other => panic!("expected an encoding error, got {other:?}"),
        }
    }

    #[test]
    fn utf16_is_named() {
        let e = text_from_bytes(vec![0xFF, 0xFE, b'a', 0], "u.xml").unwrap_err();
        assert!(e.to_string().contains("UTF-16"), "{e}");
        assert!(
            e.to_string().starts_with("u.xml:1:1: byte offset 0:"),
            "{e}"
        );
    }

    #[test]
    fn long_numbers_are_written_with_an_exponent() {
        assert_eq!(short_number(1e250), "1e250");
        assert_eq!(short_number(-1.5e-9), "-1.5e-9");
        assert_eq!(short_number(0.25), "0.25");
        assert_eq!(short_number(f64::INFINITY), "inf");
        assert_eq!(short_number(0.0), "0");
    }

    #[test]
    fn utf8_text_is_returned_unchanged() {
        assert_eq!(text_from_bytes("å\nb".into(), "x").unwrap(), "å\nb");
    }
}
