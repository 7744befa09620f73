//! The C3D container: the 512-byte header block, the parameter section and the processor
//! formats its numbers are written in. Every read is bounds-checked; nothing here panics on
//! any input, and nothing is allocated beyond what the file's own length can hold.

use crate::error::Error;

/// Bytes per C3D block.
pub(super) const BLOCK: usize = 512;

/// How the writing machine stored numbers (parameter section byte 4: 84, 85, 86).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Processor {
    /// Little-endian integers, IEEE floats.
    Intel,
    /// Little-endian integers, DEC (VAX F_floating) floats.
    Dec,
    /// Big-endian integers and IEEE floats (SGI/MIPS).
    Mips,
}

impl Processor {
    pub(super) fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Processor::Mips => u16::from_be_bytes(b),
            _ => u16::from_le_bytes(b),
        }
    }

    pub(super) fn i16(self, b: [u8; 2]) -> i16 {
        self.u16(b) as i16
    }

    /// A 4-byte float. VAX F_floating keeps the IEEE fields with the two 16-bit words
    /// swapped, an exponent bias of 128 instead of 127 and the hidden bit as 0.1f instead of
    /// 1.f: value = (IEEE reading of the word-swapped bytes) / 4, and 0 when the exponent is 0.
    pub(super) fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Processor::Intel => f32::from_le_bytes(b),
            Processor::Mips => f32::from_be_bytes(b),
            Processor::Dec => {
                let exponent = ((b[1] & 0x7f) << 1) | (b[0] >> 7);
                if exponent == 0 {
                    0.0
                } else {
                    f32::from_le_bytes([b[2], b[3], b[0], b[1]]) / 4.0
                }
            }
        }
    }

    /// True when the float's sign bit is set (−0.0 included): a negative residual word.
    pub(super) fn f32_sign(self, b: [u8; 4]) -> bool {
        match self {
            Processor::Intel => b[3] & 0x80 != 0,
            Processor::Dec => b[1] & 0x80 != 0,
            Processor::Mips => b[0] & 0x80 != 0,
        }
    }
}

/// The fields of the header block that the reader uses (C3D manual, "The header section").
#[derive(Clone, Debug)]
pub(super) struct Header {
    pub processor: Processor,
    /// Word 2: 3-D points per frame.
    pub points: u16,
    /// Word 3: analog values per 3-D frame (channels × samples per frame).
    pub analog_per_frame: u16,
    /// Words 4 and 5: first and last frame numbers (1-based).
    pub first_frame: u16,
    pub last_frame: u16,
    /// Words 7–8: POINT:SCALE; negative means float storage.
    pub scale: f32,
    /// Word 9: first block of the data section (1-based).
    pub data_start: u16,
    /// Word 10: analog samples per channel per 3-D frame.
    pub analog_subframes: u16,
    /// Words 11–12: 3-D frame rate (Hz).
    pub rate: f32,
}

/// A parameter's values as stored (types −1, 1, 2, 4 of the C3D manual).
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Values {
    Char(Vec<u8>),
    Byte(Vec<u8>),
    Int(Vec<i16>),
    Float(Vec<f32>),
}

/// One parameter: `GROUP:NAME`, its dimensions (first varies fastest) and values.
#[derive(Clone, Debug)]
pub(super) struct Parameter {
    pub group: String,
    pub name: String,
    pub dims: Vec<usize>,
    pub values: Values,
}

/// The parameter section plus the header, with typed look-ups whose errors name the
/// parameter.
#[derive(Clone, Debug)]
pub(super) struct Parameters {
    pub source: String,
    pub list: Vec<Parameter>,
}

pub(super) fn error(
    source: &str,
    location: impl Into<String>,
    message: impl Into<String>,
) -> Error {
    Error::Motion {
        file: source.to_string(),
        location: location.into(),
        message: message.into(),
    }
}

fn take<const N: usize>(bytes: &[u8], at: usize) -> Option<[u8; N]> {
    bytes.get(at..at.checked_add(N)?)?.try_into().ok()
}

/// Reads the header block and the parameter section.
pub(super) fn read_header_and_parameters(
    bytes: &[u8],
    source: &str,
) -> crate::Result<(Header, Parameters)> {
    let err = |loc: &str, msg: String| error(source, loc, msg);
    if bytes.len() < BLOCK {
        return Err(err(
            "header",
            format!(
                "{} bytes: a C3D file has at least one 512-byte header block",
                bytes.len()
            ),
        ));
    }
    if bytes[1] != 0x50 {
        return Err(err(
            "header",
            format!("key byte is {:#04x}, not 0x50: not a C3D file", bytes[1]),
        ));
    }
    let param_block = bytes[0] as usize;
    if param_block < 2 {
        return Err(err(
            "header",
            format!("parameter section starts at block {param_block} (must be ≥ 2)"),
        ));
    }
    let param_start = (param_block - 1) * BLOCK;
    let Some(param_head) = take::<4>(bytes, param_start) else {
        return Err(err(
            "header",
            format!(
                "parameter section at block {param_block} lies beyond the end of the file ({} bytes)",
                bytes.len()
            ),
        ));
    };
    let processor = match param_head[3] {
        84 => Processor::Intel,
        85 => Processor::Dec,
        86 => Processor::Mips,
        p => {
            return Err(err(
                "parameter section",
                format!("processor type {p} (must be 84 Intel, 85 DEC or 86 MIPS)"),
            ));
        }
    };
    // The header is a full block, so these reads cannot fail.
    let w = |word: usize| processor.u16([bytes[2 * word - 2], bytes[2 * word - 1]]);
    let f = |word: usize| {
        let i = 2 * word - 2;
        processor.f32([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]])
    };
    let header = Header {
        processor,
        points: w(2),
        analog_per_frame: w(3),
        first_frame: w(4),
        last_frame: w(5),
        scale: f(7),
        data_start: w(9),
        analog_subframes: w(10),
        rate: f(11),
    };
    if (header.data_start as usize) <= param_block {
        return Err(err(
            "header",
            format!(
                "data section starts at block {} but the parameter section at block {param_block}",
                header.data_start
            ),
        ));
    }
    let data_byte = (header.data_start as usize - 1) * BLOCK;
    if data_byte > bytes.len() {
        return Err(err(
            "header",
            format!(
                "data section starts at block {} (byte {data_byte}) beyond the end of the file ({} bytes): truncated",
                header.data_start,
                bytes.len()
            ),
        ));
    }
    let list = parse_parameters(&bytes[..data_byte], param_start + 4, processor, source)?;
    Ok((
        header,
        Parameters {
            source: source.to_string(),
            list,
        },
    ))
}

/// Parameter records from `pos` to the end of `section` (which stops at the data section).
///
/// A record: i8 name length (negative = locked; 0 ends the section), i8 id (negative: a
/// group with that id; positive: a parameter of that group), the name, a 16-bit offset from
/// the offset field to the next record (0 ends the section), then for a group a described
/// text, for a parameter: i8 type (−1 char, 1 byte, 2 int16, 4 float), u8 dimension count,
/// the dimensions (u8 each), the values (first dimension fastest), and a description.
fn parse_parameters(
    section: &[u8],
    mut pos: usize,
    processor: Processor,
    source: &str,
) -> crate::Result<Vec<Parameter>> {
    let mut groups: Vec<(i8, String)> = Vec::new();
    let mut raw: Vec<(i8, String, usize, Parameter)> = Vec::new();
    let trunc = |what: &str, at: usize| {
        error(
            source,
            format!("parameter section, byte {at}"),
            format!("{what} runs past the start of the data section: truncated or corrupt"),
        )
    };
    // The section may also end at a block boundary without a terminator.
    while let Some([len, id]) = take::<2>(section, pos) {
        let (len, id) = (len as i8, id as i8);
        if len == 0 || id == 0 {
            break;
        }
        let n = len.unsigned_abs() as usize;
        let name_at = pos + 2;
        let name_bytes = section
            .get(name_at..name_at + n)
            .ok_or_else(|| trunc("a record name", pos))?;
        let name = String::from_utf8_lossy(name_bytes)
            .trim()
            .to_ascii_uppercase();
        let off_at = name_at + n;
        let offset = take::<2>(section, off_at)
            .map(|b| processor.u16(b) as usize)
            .ok_or_else(|| trunc("a record offset", pos))?;
        let body = off_at + 2;
        if id < 0 {
            let d = *section
                .get(body)
                .ok_or_else(|| trunc("a group description", pos))? as usize;
            section
                .get(body + 1..body + 1 + d)
                .ok_or_else(|| trunc("a group description", pos))?;
            if groups.iter().any(|(g, _)| *g == id) {
                return Err(error(
                    source,
                    format!("parameter section, group \"{name}\""),
                    format!("group id {} defined twice", -(id as i32)),
                ));
            }
            groups.push((id, name));
        } else {
            let [kind, ndims] = take::<2>(section, body).ok_or_else(|| trunc("parameter", pos))?;
            let kind = kind as i8;
            let dims: Vec<usize> = section
                .get(body + 2..body + 2 + ndims as usize)
                .ok_or_else(|| trunc("parameter dimensions", pos))?
                .iter()
                .map(|&d| d as usize)
                .collect();
            let count = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
            let size = match kind {
                -1 | 1 => 1,
                2 => 2,
                4 => 4,
                k => {
                    return Err(error(
                        source,
                        format!("parameter \"{name}\" (byte {pos})"),
                        format!("data type {k} (must be −1 char, 1 byte, 2 integer or 4 float)"),
                    ));
                }
            };
            let data_at = body + 2 + ndims as usize;
            let data = count
                .and_then(|c| c.checked_mul(size))
                .and_then(|b| section.get(data_at..data_at.checked_add(b)?))
                .ok_or_else(|| trunc(&format!("the values of parameter \"{name}\""), pos))?;
            let values = match kind {
                -1 => Values::Char(data.to_vec()),
                1 => Values::Byte(data.to_vec()),
                2 => Values::Int(
                    data.chunks_exact(2)
                        .map(|c| processor.i16([c[0], c[1]]))
                        .collect(),
                ),
                _ => Values::Float(
                    data.chunks_exact(4)
                        .map(|c| processor.f32([c[0], c[1], c[2], c[3]]))
                        .collect(),
                ),
            };
            let param = Parameter {
                group: String::new(),
                name: name.clone(),
                dims,
                values,
            };
            raw.push((id, name, pos, param));
        }
        if offset == 0 {
            break;
        }
        pos = off_at + offset;
    }
    let mut list: Vec<Parameter> = Vec::with_capacity(raw.len());
    for (id, name, at, mut p) in raw {
        let Some((_, group)) = groups.iter().find(|(g, _)| *g == -id) else {
            return Err(error(
                source,
                format!("parameter \"{name}\" (byte {at})"),
                format!("belongs to group id {id}, which the file does not define"),
            ));
        };
        p.group = group.clone();
        if list.iter().any(|q| q.group == p.group && q.name == p.name) {
            return Err(error(
                source,
                format!("parameter {}:{}", p.group, p.name),
                "defined twice",
            ));
        }
        list.push(p);
    }
    Ok(list)
}

impl Parameters {
    pub(super) fn get(&self, group: &str, name: &str) -> Option<&Parameter> {
        self.list
            .iter()
            .find(|p| p.group == group && p.name == name)
    }

    pub(super) fn error(&self, group: &str, name: &str, message: impl Into<String>) -> Error {
        error(&self.source, format!("parameter {group}:{name}"), message)
    }

    /// Numeric values as f64 (integers, bytes or floats); `None` when absent.
    pub(super) fn numbers(&self, group: &str, name: &str) -> crate::Result<Option<Vec<f64>>> {
        let Some(p) = self.get(group, name) else {
            return Ok(None);
        };
        Ok(Some(match &p.values {
            Values::Int(v) => v.iter().map(|&x| x as f64).collect(),
            Values::Byte(v) => v.iter().map(|&x| x as f64).collect(),
            Values::Float(v) => v.iter().map(|&x| x as f64).collect(),
            Values::Char(_) => {
                return Err(self.error(group, name, "holds text where numbers are expected"));
            }
        }))
    }

    /// Integer values; 16-bit integers are read as unsigned when `unsigned` (counts above
    /// 32767 are stored that way), floats must be whole numbers.
    pub(super) fn integers(
        &self,
        group: &str,
        name: &str,
        unsigned: bool,
    ) -> crate::Result<Option<Vec<i64>>> {
        let Some(p) = self.get(group, name) else {
            return Ok(None);
        };
        Ok(Some(match &p.values {
            Values::Int(v) if unsigned => v.iter().map(|&x| x as u16 as i64).collect(),
            Values::Int(v) => v.iter().map(|&x| x as i64).collect(),
            Values::Byte(v) => v.iter().map(|&x| x as i64).collect(),
            Values::Float(v) => {
                let mut out = Vec::with_capacity(v.len());
                for &x in v {
                    if x.fract() != 0.0 || !x.is_finite() || x.abs() > 1e9 {
                        return Err(self.error(group, name, format!("{x} is not an integer")));
                    }
                    out.push(x as i64);
                }
                out
            }
            Values::Char(_) => {
                return Err(self.error(group, name, "holds text where integers are expected"));
            }
        }))
    }

    /// The first value of an integer parameter.
    pub(super) fn integer(
        &self,
        group: &str,
        name: &str,
        unsigned: bool,
    ) -> crate::Result<Option<i64>> {
        match self.integers(group, name, unsigned)? {
            None => Ok(None),
            Some(v) => match v.first() {
                Some(&x) => Ok(Some(x)),
                None => Err(self.error(group, name, "has no value")),
            },
        }
    }

    /// Text values: a char array of dimensions [length, count…] is `count` strings, each
    /// with trailing blanks and NULs removed; a 0- or 1-dimensional one is one string.
    pub(super) fn strings(&self, group: &str, name: &str) -> crate::Result<Option<Vec<String>>> {
        let Some(p) = self.get(group, name) else {
            return Ok(None);
        };
        let Values::Char(bytes) = &p.values else {
            return Err(self.error(group, name, "holds numbers where text is expected"));
        };
        let clean = |b: &[u8]| {
            String::from_utf8_lossy(b)
                .trim_end_matches([' ', '\0'])
                .trim_start()
                .to_string()
        };
        if p.dims.len() <= 1 {
            return Ok(Some(vec![clean(bytes)]));
        }
        let len = p.dims[0];
        if len == 0 {
            return Ok(Some(vec![String::new(); bytes.len()]));
        }
        Ok(Some(bytes.chunks(len).map(clean).collect()))
    }

    /// A list that C3D splits over `NAME`, `NAME2`, `NAME3`… when it has more than 255
    /// entries (`LABELS`, `SCALE`, `OFFSET`, `UNITS`): the parts concatenated. `read` reads
    /// one part by name.
    pub(super) fn continued<T>(
        &self,
        name: &str,
        mut read: impl FnMut(&str) -> crate::Result<Option<Vec<T>>>,
    ) -> crate::Result<Option<Vec<T>>> {
        let Some(mut all) = read(name)? else {
            return Ok(None);
        };
        for k in 2.. {
            match read(&format!("{name}{k}"))? {
                Some(more) => all.extend(more),
                None => break,
            }
        }
        Ok(Some(all))
    }
}
