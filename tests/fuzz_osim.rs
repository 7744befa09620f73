//! Robustness of the .osim reader: thousands of deterministically corrupted copies of real
//! models (truncated, lines deleted, duplicated or swapped, numbers replaced by junk,
//! attributes or closing tags deleted, random bytes inserted). Loading each must return
//! `Ok` or `Err`, never panic; when a corrupted copy still loads, the dynamics at its
//! default pose must not panic either.
//!
//! Also: every model of the reference opensim-models collection loads.

use musculo::model::LoadOptions;
use musculo::{Data, Error, Model, dynamics};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

const DEMO: &str = include_str!("../models/demo.osim");

/// SplitMix64 (Steele, Lea & Flood 2014): small, fast, and the same on every platform.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in 0..n (n > 0).
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Replacements for a number: junk that must be rejected, and extreme values that parse
/// and reach the dynamics.
const NUMBER_JUNK: &[&str] = &[
    "abc", "nan", "NaN", "-1e400", "1e999", "inf", "-inf", "", "1 2", "1,5", "--1", "0x10", "1e",
    ".", "0", "-0", "-1", "1e300", "-1e300", "1e-300", "5e-324", "1e20", "-3.5", "7",
];

/// Fragments inserted at random places.
const INSERTS: &[&str] = &[
    "<",
    ">",
    "&",
    "\"",
    "'",
    "/",
    "=",
    "</",
    "/>",
    "<!--",
    "-->",
    "]]>",
    "<![CDATA[",
    "&amp;",
    "&#0;",
    "&#x110000;",
    "&unknown;",
    "\u{0}",
    "\u{7}",
    "\u{FFFE}",
    "é",
    "\u{10FFFF}",
    " ",
    "\n",
    "x",
    "9",
    "-",
    ".",
    "e",
    "<a>",
    "</a>",
    "<Body name=\"x\"/>",
    "<?pi?>",
    "<!DOCTYPE x>",
];

/// Elements inserted after a random opening tag: known tags with odd values, so that the
/// reader's semantic checks (not only the XML parser) meet them.
const ELEMENTS: &[&str] = &[
    "<locked>true</locked>",
    "<clamped>true</clamped>",
    "<prescribed>true</prescribed>",
    "<reverse>true</reverse>",
    "<isEnforced>false</isEnforced>",
    "<mass>-1</mass>",
    "<mass>0</mass>",
    "<inertia>0 0 0 0 0 0</inertia>",
    "<inertia>1 1 3 0 0 0</inertia>",
    "<range>1 0</range>",
    "<range>0 0</range>",
    "<default_value>1e10</default_value>",
    "<default_value>-3.14159</default_value>",
    "<scale_factor>0</scale_factor>",
    "<axis>0 0 0</axis>",
    "<axis>1 1 0</axis>",
    "<coordinates>a b c</coordinates>",
    "<coordinates></coordinates>",
    "<Coordinate name=\"extra\"/>",
    "<Coordinate/>",
    "<socket_parent_frame>/ground</socket_parent_frame>",
    "<socket_child_frame>/ground</socket_child_frame>",
    "<socket_parent>..</socket_parent>",
    "<PhysicalOffsetFrame name=\"loop\"><socket_parent>loop</socket_parent></PhysicalOffsetFrame>",
    "<Constant><value>1e300</value></Constant>",
    "<LinearFunction><coefficients>1</coefficients></LinearFunction>",
    "<LinearFunction><coefficients>2 3 4</coefficients></LinearFunction>",
    "<PolynomialFunction><coefficients></coefficients></PolynomialFunction>",
    "<SimmSpline><x>0</x><y>0</y></SimmSpline>",
    "<SimmSpline><x>-1e308 1e308</x><y>0 1</y></SimmSpline>",
    "<PiecewiseLinearFunction><x>0 1</x><y>0 1</y></PiecewiseLinearFunction>",
    "<GCVSpline><half_order>3</half_order><x>0 1 2</x><y>0 1 0</y></GCVSpline>",
    "<GCVSpline><half_order>1e300</half_order><x>0 1 2</x><y>0 1 0</y></GCVSpline>",
    "<GCVSpline><half_order>1</half_order><x>0</x><y>2</y></GCVSpline>",
    "<MultiplierFunction><scale>0</scale><function><Constant/></function></MultiplierFunction>",
    "<MultiplierFunction><function><MultiplierFunction><function></function></MultiplierFunction></function></MultiplierFunction>",
    "<Sine/>",
    "<radius>-1</radius>",
    "<dimensions>1 0 1</dimensions>",
    "<optimal_fiber_length>0</optimal_fiber_length>",
    "<max_isometric_force>-5</max_isometric_force>",
    "<wrap_object>nothing</wrap_object>",
    "<socket_coordinate>/jointset/a/b</socket_coordinate>",
    "<objects></objects>",
    "<groups/>",
    "<FancyThing/>",
];

/// Where the mutations can act, found once per input.
struct Targets<'t> {
    text: &'t str,
    /// Byte ranges of the lines (with their newline).
    lines: Vec<(usize, usize)>,
    /// Byte ranges of number tokens in text or attribute values.
    numbers: Vec<(usize, usize)>,
    /// Byte ranges of attributes, with their leading space: ` name="value"`.
    attributes: Vec<(usize, usize)>,
    /// Byte ranges of closing tags `</...>`.
    closing_tags: Vec<(usize, usize)>,
    /// Byte ranges of names and references: `name` attribute values and one-word element
    /// texts that are not numbers (coordinate names, socket paths, wrap object names).
    identifiers: Vec<(usize, usize)>,
    /// Byte offsets just after an opening tag, where an element can be inserted.
    element_slots: Vec<usize>,
}

impl<'t> Targets<'t> {
    fn new(text: &'t str) -> Self {
        let bytes = text.as_bytes();
        let mut lines = Vec::new();
        let mut start = 0;
        for l in text.split_inclusive('\n') {
            lines.push((start, start + l.len()));
            start += l.len();
        }
        let is_delim = |b: u8| b.is_ascii_whitespace() || b == b'<' || b == b'>' || b == b'"';
        let is_num = |b: u8| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E');
        let mut numbers = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            if is_num(bytes[i]) && (i == 0 || is_delim(bytes[i - 1])) {
                let mut j = i;
                while j < bytes.len() && is_num(bytes[j]) {
                    j += 1;
                }
                if (j == bytes.len() || is_delim(bytes[j]))
                    && bytes[i..j].iter().any(u8::is_ascii_digit)
                {
                    numbers.push((i, j));
                }
                i = j.max(i + 1);
            } else {
                i += 1;
            }
        }
        let mut attributes = Vec::new();
        for (eq, _) in text.match_indices("=\"") {
            let name_start = text[..eq]
                .rfind(|c: char| c.is_ascii_whitespace())
                .unwrap_or(eq);
            let Some(close) = text[eq + 2..].find('"') else {
                continue;
            };
            attributes.push((name_start, eq + 2 + close + 1));
        }
        let closing_tags = text
            .match_indices("</")
            .filter_map(|(i, _)| text[i..].find('>').map(|e| (i, i + e + 1)))
            .collect();
        let mut identifiers: Vec<(usize, usize)> = text
            .match_indices(" name=\"")
            .filter_map(|(i, m)| {
                let start = i + m.len();
                text[start..].find('"').map(|e| (start, start + e))
            })
            .collect();
        let mut element_slots = Vec::new();
        for (i, _) in text.match_indices('>') {
            let after = &text[i + 1..];
            let Some(end) = after.find('<') else { continue };
            let word = &after[..end];
            let tag = &text[text[..i].rfind('<').unwrap_or(0)..i];
            let opening = !tag.starts_with("</")
                && !tag.starts_with("<?")
                && !tag.starts_with("<!")
                && !tag.ends_with('/');
            if opening && !word.trim().is_empty() && !word.trim().contains(char::is_whitespace) {
                let t = word.trim();
                if t.parse::<f64>().is_err() && !matches!(t, "true" | "false") {
                    let lead = word.len() - word.trim_start().len();
                    identifiers.push((i + 1 + lead, i + 1 + lead + t.len()));
                }
            }
            if opening && !after.starts_with(|c: char| c.is_ascii_alphanumeric()) {
                element_slots.push(i + 1);
            }
        }
        Targets {
            text,
            lines,
            numbers,
            attributes,
            closing_tags,
            identifiers,
            element_slots,
        }
    }

    fn splice(&self, range: (usize, usize), with: &str) -> String {
        let mut s = String::with_capacity(self.text.len() + with.len());
        s.push_str(&self.text[..range.0]);
        s.push_str(with);
        s.push_str(&self.text[range.1..]);
        s
    }

    fn line(&self, k: usize) -> &str {
        let (a, b) = self.lines[k];
        &self.text[a..b]
    }
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    i = i.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// A corrupted copy and what was done to it (for the failure report).
struct Case {
    what: String,
    text: String,
}

/// One random mutation of `t`.
fn mutate(t: &Targets, rng: &mut SplitMix64) -> Case {
    let n_lines = t.lines.len();
    match rng.below(9) {
        7 if !t.identifiers.is_empty() => {
            // A name or reference replaced by another one from the same file (duplicates,
            // references to the wrong kind of component, cycles), or by a missing one.
            let r = *rng.pick(&t.identifiers);
            let other = if rng.below(8) == 0 {
                "missing".to_string()
            } else {
                let o = *rng.pick(&t.identifiers);
                t.text[o.0..o.1].to_string()
            };
            Case {
                what: format!(
                    "replace identifier `{}` at byte {} with `{other}`",
                    &t.text[r.0..r.1],
                    r.0
                ),
                text: t.splice(r, &other),
            }
        }
        8 if !t.element_slots.is_empty() => {
            let at = *rng.pick(&t.element_slots);
            let element = *rng.pick(ELEMENTS);
            Case {
                what: format!("insert `{element}` at byte {at}"),
                text: t.splice((at, at), element),
            }
        }
        0 => {
            let k = rng.below(n_lines);
            Case {
                what: format!("delete line {}", k + 1),
                text: t.splice(t.lines[k], ""),
            }
        }
        1 => {
            let k = rng.below(n_lines);
            let line = t.line(k);
            Case {
                what: format!("duplicate line {}", k + 1),
                text: t.splice((t.lines[k].0, t.lines[k].0), line),
            }
        }
        2 => {
            let (a, b) = (rng.below(n_lines), rng.below(n_lines));
            let (a, b) = (a.min(b), a.max(b));
            let mut s = String::with_capacity(t.text.len());
            s.push_str(&t.text[..t.lines[a].0]);
            s.push_str(t.line(b).trim_end_matches('\n'));
            s.push_str(if t.line(a).ends_with('\n') { "\n" } else { "" });
            if a != b {
                s.push_str(&t.text[t.lines[a].1..t.lines[b].0]);
                s.push_str(t.line(a).trim_end_matches('\n'));
                s.push_str(if t.line(b).ends_with('\n') { "\n" } else { "" });
            }
            s.push_str(&t.text[t.lines[b].1..]);
            Case {
                what: format!("swap lines {} and {}", a + 1, b + 1),
                text: s,
            }
        }
        3 if !t.numbers.is_empty() => {
            let r = *rng.pick(&t.numbers);
            let junk = *rng.pick(NUMBER_JUNK);
            Case {
                what: format!(
                    "replace number `{}` at byte {} with `{junk}`",
                    &t.text[r.0..r.1],
                    r.0
                ),
                text: t.splice(r, junk),
            }
        }
        4 if !t.attributes.is_empty() => {
            let r = *rng.pick(&t.attributes);
            Case {
                what: format!(
                    "delete attribute `{}` at byte {}",
                    t.text[r.0..r.1].trim(),
                    r.0
                ),
                text: t.splice(r, ""),
            }
        }
        5 if !t.closing_tags.is_empty() => {
            let r = *rng.pick(&t.closing_tags);
            Case {
                what: format!("delete closing tag `{}` at byte {}", &t.text[r.0..r.1], r.0),
                text: t.splice(r, ""),
            }
        }
        _ => {
            let at = floor_char_boundary(t.text, rng.below(t.text.len() + 1));
            let n = 1 + rng.below(4);
            let insert: String = (0..n).map(|_| *rng.pick(INSERTS)).collect();
            Case {
                what: format!("insert {insert:?} at byte {at}"),
                text: t.splice((at, at), &insert),
            }
        }
    }
}

/// Several number replacements at once: values that parse, to reach deeper checks and the
/// dynamics with odd but finite numbers.
fn mutate_numbers(t: &Targets, rng: &mut SplitMix64) -> Case {
    const FINITE: &[&str] = &[
        "0", "-0", "-1", "1e300", "-1e300", "1e-300", "5e-324", "1e20", "-3.5", "7",
    ];
    let k = 1 + rng.below(5);
    let mut picks: Vec<(usize, usize)> = (0..k).map(|_| *rng.pick(&t.numbers)).collect();
    picks.sort();
    picks.dedup();
    let mut s = String::with_capacity(t.text.len());
    let mut at = 0;
    let mut what = Vec::new();
    for r in picks {
        let v = *rng.pick(FINITE);
        s.push_str(&t.text[at..r.0]);
        s.push_str(v);
        what.push(format!("`{}`@{}→`{v}`", &t.text[r.0..r.1], r.0));
        at = r.1;
    }
    s.push_str(&t.text[at..]);
    Case {
        what: format!("replace numbers {}", what.join(", ")),
        text: s,
    }
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "<non-string panic payload>".to_string()
    }
}

/// Loads `text` and, if it loads, runs the dynamics at the default pose; returns whether it
/// loaded, or the panic.
fn load_and_run(text: &str, source: &str) -> Result<bool, String> {
    let loaded = catch_unwind(|| Model::from_osim_str(text, source))
        .map_err(|p| format!("parse panicked: {}", panic_message(&*p)))?;
    let Ok(model) = loaded else { return Ok(false) };
    catch_unwind(AssertUnwindSafe(|| {
        let mut data = Data::new(&model);
        let q = model.default_q();
        let zeros = vec![0.0; model.nq()];
        let _ = dynamics::forward_kinematics(&model, &mut data, &q);
        let _ = dynamics::crba(&model, &mut data, &q);
        let _ = dynamics::rnea(&model, &mut data, &q, &zeros, &zeros);
    }))
    .map_err(|p| format!("dynamics panicked: {}", panic_message(&*p)))?;
    Ok(true)
}

/// Runs `random_cases` random mutations plus `truncations` truncations spread over the file
/// (a tenth of each in unoptimised builds, which are many times slower).
fn fuzz(label: &str, text: &str, seed: u64, truncations: usize, random_cases: usize) {
    let (truncations, random_cases) = if cfg!(debug_assertions) {
        (truncations / 10, random_cases / 10)
    } else {
        (truncations, random_cases)
    };
    let started = std::time::Instant::now();
    if let Err(e) = Model::from_osim_str(text, label) {
        panic!("{label} must load unedited: {e}");
    }
    let targets = Targets::new(text);
    let mut rng = SplitMix64(seed);
    let mut tried = 0usize;
    let mut parsed = 0usize;
    let mut panics: Vec<String> = Vec::new();
    let mut run = |what: String, corrupted: &str| {
        tried += 1;
        match load_and_run(corrupted, label) {
            Ok(true) => parsed += 1,
            Ok(false) => {}
            Err(p) => panics.push(format!("{label}: {what}: {p}")),
        }
    };
    // Truncations evenly spread over the file, each jittered within its slot.
    let slot = (text.len() / truncations.max(1)).max(1);
    for k in 0..truncations {
        let at = floor_char_boundary(text, k * slot + rng.below(slot));
        run(format!("truncate at byte {at}"), &text[..at]);
    }
    for k in 0..random_cases {
        // One case in four changes several numbers to finite values; the rest are one
        // mutation of any kind.
        let case = if k % 4 == 3 && !targets.numbers.is_empty() {
            mutate_numbers(&targets, &mut rng)
        } else {
            mutate(&targets, &mut rng)
        };
        run(case.what, &case.text);
    }
    println!(
        "{label}: {tried} corrupted copies tried, {parsed} loaded, {} panicked ({:.1} s)",
        panics.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(
        panics.is_empty(),
        "{} of {tried} corrupted copies panicked:\n{}",
        panics.len(),
        panics
            .iter()
            .take(20)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// The text of a reference file, or None (after printing why) when it is absent and not
/// required.
fn reference_text(relative: &str) -> Option<String> {
    match musculo::reference::file(relative) {
        Some(p) => {
            Some(std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
        }
        None => {
            assert!(
                !musculo::reference::required(),
                "reference file {relative} not found under {} (MUSCULO_REQUIRE_REFERENCE=1)",
                musculo::reference::directory().display()
            );
            println!("skipped: reference data not found ({relative})");
            None
        }
    }
}

#[test]
fn corrupted_demo_model_never_panics() {
    fuzz("demo.osim", DEMO, 0x5EED_0001, 300, 50_000);
}

#[test]
fn corrupted_arm26_never_panics() {
    if let Some(text) = reference_text("opensim-models/Models/Arm26/arm26.osim") {
        fuzz("arm26.osim", &text, 0x5EED_0002, 300, 20_000);
    }
}

#[test]
fn corrupted_gait2392_never_panics() {
    if let Some(text) =
        reference_text("opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim")
    {
        fuzz(
            "gait2392_thelen2003muscle.osim",
            &text,
            0x5EED_0003,
            300,
            3000,
        );
    }
}

fn osim_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            osim_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "osim") {
            out.push(p);
        }
    }
}

/// The one reference model whose inertia violates the triangle inequality (its toes), which
/// release builds of OpenSim accept.
const NONPHYSICAL_INERTIA_FILE: &str =
    "Tutorials/Estimating_Joint_Reaction_Loads/subject01_simbody_adjusted_StaticOp.osim";

#[test]
fn every_reference_opensim_model_loads() {
    let root = musculo::reference::directory().join("opensim-models");
    let mut files = Vec::new();
    osim_files(&root, &mut files);
    files.sort();
    if files.is_empty() {
        assert!(
            !musculo::reference::required(),
            "no .osim file under {} (MUSCULO_REQUIRE_REFERENCE=1)",
            root.display()
        );
        println!("skipped: reference data not found ({})", root.display());
        return;
    }
    let lenient = LoadOptions::default();
    let strict = LoadOptions { strict: true };
    let mut failures = Vec::new();
    let mut need_option = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&root).unwrap().display().to_string();
        match Model::from_osim_file_with(f, &lenient) {
            Ok(m) => println!(
                "{rel}: {} bodies, nq = {}, {} warnings",
                m.bodies.len(),
                m.nq(),
                m.warnings.len()
            ),
            Err(e) => failures.push(format!("{rel}: {e}")),
        }
        if let Err(e) = Model::from_osim_file_with(f, &strict) {
            need_option.push((rel, e));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} models fail to load:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
    let names: Vec<&str> = need_option.iter().map(|(r, _)| r.as_str()).collect();
    assert_eq!(
        names,
        [NONPHYSICAL_INERTIA_FILE],
        "models that strict reading refuses"
    );
    match &need_option[0].1 {
        Error::Model {
            element, message, ..
        } => {
            assert!(
                element.contains("toes_r"),
                "the error should name toes_r: {element}: {message}"
            );
            assert!(message.contains("triangle inequality"), "{message}");
        }
        other => panic!("expected Error::Model naming toes_r, got {other}"),
    }
    println!("{} reference models load", files.len());
}
