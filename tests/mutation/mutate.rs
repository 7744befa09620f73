//! Deterministic mutations of a file's bytes, as a new user's tools and typos produce them:
//! truncations, byte flips, deleted and repeated ranges, deleted, repeated and swapped lines,
//! numbers replaced by extremes (NaN, ±inf, huge, negative, 0), tag or keyword names swapped
//! with other names of the same file, and stray fragments. Text-aware mutations work on the
//! bytes too, so they reach the ASCII headers of binary formats (`.npy`, `.c3d`).

/// SplitMix64 (Steele, Lea & Flood 2014): small, fast and the same on every platform.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in 0..n (0 when n is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// What replaces a number: values that parse but are out of any range, and junk.
const NUMBERS: &[&str] = &[
    "NaN",
    "nan",
    "inf",
    "-inf",
    "Infinity",
    "1e308",
    "-1e308",
    "1e999",
    "1.8e308",
    "5e-324",
    "-1",
    "-0",
    "0",
    "0.0",
    "1",
    "2",
    "65535",
    "65536",
    "2147483648",
    "4294967296",
    "9223372036854775808",
    "99999999999999999999",
    "-99999999",
    "1e9",
    "",
    "x",
    "1.2.3",
    "--1",
    "1e",
    "0x1F",
];

/// Fragments inserted at random places: separators, markup, odd characters.
const TEXT_FRAGMENTS: &[&str] = &[
    "\t", "\n", "\r\n", " ", ",", ";", "=", "-", ".", "#", "\"", "'", "\u{feff}", "é", "\u{0}",
    "\u{7f}", "\u{fffd}", "{", "}", "(", ")", "[", "]", ":",
];

const XML_FRAGMENTS: &[&str] = &[
    "<",
    ">",
    "&",
    "</",
    "/>",
    "<!--",
    "-->",
    "<![CDATA[x]]>",
    "&amp;",
    "&#0;",
    "&#x110000;",
    "&unknown;",
    "<a>",
    "</a>",
    "<a/>",
    "<?pi?>",
    "<!DOCTYPE x>",
    "<!DOCTYPE x [<!ENTITY e \"eeeeeeee\">]>",
    "&e;",
    " name=\"dup\"",
    " file=\"other.xml\"",
];

/// Where the mutations act, found once per seed.
pub struct Targets {
    /// Byte ranges of the lines, newline included.
    lines: Vec<(usize, usize)>,
    /// Byte ranges of number tokens.
    numbers: Vec<(usize, usize)>,
    /// Byte ranges of words: XML tag names, or identifiers/keywords in other text.
    words: Vec<(usize, usize)>,
    xml: bool,
}

fn is_number_byte(b: u8) -> bool {
    b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E')
}

fn is_word_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b':' | b'#' | b'.')
}

impl Targets {
    pub fn new(bytes: &[u8], xml: bool) -> Targets {
        let mut lines = Vec::new();
        let mut start = 0;
        for (i, &b) in bytes.iter().enumerate() {
            if b == b'\n' {
                lines.push((start, i + 1));
                start = i + 1;
            }
        }
        if start < bytes.len() {
            lines.push((start, bytes.len()));
        }
        let mut numbers = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let starts = is_number_byte(bytes[i])
                && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_'));
            if starts {
                let mut j = i;
                while j < bytes.len() && is_number_byte(bytes[j]) {
                    j += 1;
                }
                if bytes[i..j].iter().any(u8::is_ascii_digit) {
                    numbers.push((i, j));
                }
                i = j;
            } else {
                i += 1;
            }
        }
        let mut words = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let starts = bytes[i].is_ascii_alphabetic()
                && (i == 0 || !is_word_byte(bytes[i - 1]))
                && (!xml || (i > 0 && (bytes[i - 1] == b'<' || bytes[i - 1] == b'/')));
            if starts {
                let mut j = i;
                while j < bytes.len() && is_word_byte(bytes[j]) {
                    j += 1;
                }
                words.push((i, j));
                i = j;
            } else {
                i += 1;
            }
        }
        Targets {
            lines,
            numbers,
            words,
            xml,
        }
    }
}

fn splice(bytes: &[u8], range: (usize, usize), with: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len() + with.len());
    out.extend_from_slice(&bytes[..range.0]);
    out.extend_from_slice(with);
    out.extend_from_slice(&bytes[range.1..]);
    out
}

/// One mutation of `bytes` (whose targets are `t`), described for the failure report. The
/// targets are those of the seed; after a first mutation they may be off by a few bytes,
/// which only makes the next mutation land elsewhere (ranges are clamped).
fn mutate_once(bytes: &[u8], t: &Targets, rng: &mut Rng) -> (String, Vec<u8>) {
    let n = bytes.len();
    let clamp = |r: (usize, usize)| (r.0.min(n), r.1.min(n).max(r.0.min(n)));
    let line = |rng: &mut Rng| -> Option<(usize, usize)> {
        (!t.lines.is_empty()).then(|| clamp(*rng.pick(&t.lines)))
    };
    match rng.below(12) {
        0 => {
            let at = rng.below(n + 1);
            (format!("truncate at byte {at}"), bytes[..at].to_vec())
        }
        1 => {
            let mut b = bytes.to_vec();
            let k = 1 + rng.below(4);
            let mut at = Vec::new();
            for _ in 0..k {
                if b.is_empty() {
                    break;
                }
                let i = rng.below(b.len());
                // Mostly printable ASCII, sometimes any byte.
                b[i] = if rng.below(4) == 0 {
                    rng.next_u64() as u8
                } else {
                    32 + rng.below(95) as u8
                };
                at.push(i);
            }
            (format!("set bytes {at:?}"), b)
        }
        2 => {
            let i = rng.below(n + 1);
            let j = (i + 1 + rng.below(64)).min(n);
            (format!("delete bytes {i}..{j}"), splice(bytes, (i, j), b""))
        }
        3 => match line(rng) {
            Some(r) => {
                let times = 1 + rng.below(3);
                let copy = bytes[r.0..r.1].repeat(times);
                (
                    format!("repeat the line at byte {} {times} more time(s)", r.0),
                    splice(bytes, (r.1, r.1), &copy),
                )
            }
            None => (String::from("unchanged"), bytes.to_vec()),
        },
        4 => match line(rng) {
            Some(r) => (
                format!("delete the line at byte {}", r.0),
                splice(bytes, r, b""),
            ),
            None => (String::from("unchanged"), bytes.to_vec()),
        },
        5 => match (line(rng), line(rng)) {
            (Some(a), Some(b)) if a.1 <= b.0 => {
                let mut out = Vec::with_capacity(n);
                out.extend_from_slice(&bytes[..a.0]);
                out.extend_from_slice(&bytes[b.0..b.1]);
                out.extend_from_slice(&bytes[a.1..b.0]);
                out.extend_from_slice(&bytes[a.0..a.1]);
                out.extend_from_slice(&bytes[b.1..]);
                (format!("swap the lines at bytes {} and {}", a.0, b.0), out)
            }
            _ => (String::from("unchanged"), bytes.to_vec()),
        },
        6 | 7 if !t.numbers.is_empty() => {
            let r = clamp(*rng.pick(&t.numbers));
            let v = *rng.pick(NUMBERS);
            (
                format!("number at byte {} set to {v:?}", r.0),
                splice(bytes, r, v.as_bytes()),
            )
        }
        8 if !t.words.is_empty() => {
            // A tag or keyword replaced by another of the same file: swapped tags, closing
            // tags that do not match, keywords in the wrong place.
            let r = clamp(*rng.pick(&t.words));
            let o = clamp(*rng.pick(&t.words));
            let other = bytes[o.0..o.1].to_vec();
            (
                format!(
                    "word at byte {} set to {:?}",
                    r.0,
                    String::from_utf8_lossy(&other)
                ),
                splice(bytes, r, &other),
            )
        }
        9 => {
            let fragments = if t.xml && rng.below(2) == 0 {
                XML_FRAGMENTS
            } else {
                TEXT_FRAGMENTS
            };
            let f = *rng.pick(fragments);
            let at = rng.below(n + 1);
            (
                format!("insert {f:?} at byte {at}"),
                splice(bytes, (at, at), f.as_bytes()),
            )
        }
        10 => {
            // A block repeated: long repeats stress counts declared in headers.
            let i = rng.below(n + 1);
            let j = (i + 1 + rng.below(512)).min(n);
            let times = 1 + rng.below(8);
            let copy = bytes[i..j].repeat(times);
            (
                format!("repeat bytes {i}..{j} {times} more time(s)"),
                splice(bytes, (j, j), &copy),
            )
        }
        _ => {
            // A binary field overwritten: 2, 4 or 8 bytes with extremes of either byte order.
            const FIELDS: &[&[u8]] = &[
                &[0, 0],
                &[0xff, 0xff],
                &[0xff, 0x7f],
                &[0x7f, 0xff],
                &[0, 0x80],
                &[0x80, 0],
                &[0, 0, 0xc0, 0x7f],
                &[0x7f, 0xc0, 0, 0],
                &[0, 0, 0x80, 0x7f],
                &[0, 0, 0x80, 0xff],
                &[0xff, 0xff, 0xff, 0xff],
                &[0xff, 0xff, 0xff, 0x7f],
                &[0, 0, 0, 0, 0, 0, 0xf8, 0x7f],
                &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xef, 0x7f],
            ];
            let f = *rng.pick(FIELDS);
            if n < f.len() {
                return (String::from("unchanged"), bytes.to_vec());
            }
            let at = rng.below(n - f.len() + 1);
            let mut b = bytes.to_vec();
            b[at..at + f.len()].copy_from_slice(f);
            (format!("field at byte {at} set to {f:02x?}"), b)
        }
    }
}

/// One to three mutations of `bytes` stacked, described.
pub fn mutate(bytes: &[u8], t: &Targets, rng: &mut Rng) -> (String, Vec<u8>) {
    let k = match rng.below(8) {
        0..=4 => 1,
        5 | 6 => 2,
        _ => 3,
    };
    let mut what = Vec::with_capacity(k);
    let mut out = bytes.to_vec();
    for _ in 0..k {
        let (w, b) = mutate_once(&out, t, rng);
        what.push(w);
        out = b;
    }
    (what.join("; "), out)
}
