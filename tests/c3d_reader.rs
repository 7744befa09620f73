//! The C3D reader against ezc3d 1.7.2's exports of the two reference trials (markers with
//! gaps, analog channels, force-platform force/moment/COP/free moment), force platforms of
//! types 1, 3 and 4 built from the same trial's signals, the three processor formats and
//! integer storage through files written here, and bad input (truncated, mutated,
//! inconsistent files) as errors — never a panic.

mod common;

use common::reference_file;
use musculo::Error;
use musculo::motion::c3d::{self, C3d, Processor};
use musculo::spatial::Vec3;
use std::panic::{AssertUnwindSafe, catch_unwind};

// ---------------------------------------------------------------------------------------
// Reference exports

/// A CSV export: header labels and rows (None = empty field).
struct Csv {
    labels: Vec<String>,
    rows: Vec<Vec<Option<f64>>>,
}

impl Csv {
    fn read(path: &std::path::Path) -> Csv {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines = text.lines();
        let labels = lines
            .next()
            .unwrap()
            .split(',')
            .map(str::to_string)
            .collect();
        let rows = lines
            .map(|l| {
                l.split(',')
                    .map(|v| (!v.is_empty()).then(|| v.parse::<f64>().unwrap()))
                    .collect()
            })
            .collect();
        Csv { labels, rows }
    }

    fn column(&self, label: &str) -> usize {
        self.labels
            .iter()
            .position(|l| l == label)
            .unwrap_or_else(|| panic!("no column {label}"))
    }
}

/// The trial, its marker export and its force-plate export, or None (skipped).
fn trial(name: &str) -> Option<(Vec<u8>, Csv, Csv)> {
    let c3d = reference_file(&format!("c3d/{name}.c3d"))?;
    let markers = reference_file(&format!("c3d/{name}_markers.csv"))?;
    let plates = reference_file(&format!("c3d/{name}_forceplates.csv"))?;
    Some((
        std::fs::read(c3d).unwrap(),
        Csv::read(&markers),
        Csv::read(&plates),
    ))
}

/// Markers (mm) against the export: same labels in the same order, same frames and times,
/// gaps at exactly the same samples, coordinates within `tol` mm. Returns the largest
/// difference and the number of gap samples.
fn compare_markers(c: &C3d, csv: &Csv, tol: f64, what: &str) -> (f64, usize) {
    let m = c.markers.as_ref().expect("markers");
    let labels: Vec<String> = csv.labels[2..]
        .iter()
        .step_by(3)
        .map(|l| l.trim_end_matches("_X").to_string())
        .collect();
    assert_eq!(m.names, labels, "{what}: marker labels");
    assert_eq!(m.n_frames(), csv.rows.len(), "{what}: frames");
    let (mut max, mut gaps) = (0.0f64, 0);
    for (f, row) in csv.rows.iter().enumerate() {
        assert_eq!(row[0], Some((f + 1) as f64), "{what}: frame column");
        assert!(
            (m.time[f] - row[1].unwrap()).abs() <= 5e-7,
            "{what}: time of frame {f}"
        );
        for (i, p) in m.frame(f).iter().enumerate() {
            let expected = &row[2 + 3 * i..5 + 3 * i];
            if expected.iter().all(Option::is_none) {
                gaps += 1;
                assert!(
                    p.iter().all(|x| x.is_nan()),
                    "{what}: frame {f} {} should be a gap",
                    m.names[i]
                );
                continue;
            }
            assert!(
                p.iter().all(|x| x.is_finite()),
                "{what}: frame {f} {} is a gap, not in the export",
                m.names[i]
            );
            for k in 0..3 {
                let d = (p[k] * 1000.0 - expected[k].unwrap()).abs();
                max = max.max(d);
                assert!(
                    d <= tol,
                    "{what}: frame {f} {} axis {k}: {} mm vs {:?}",
                    m.names[i],
                    p[k] * 1000.0,
                    expected[k]
                );
            }
        }
    }
    (max, gaps)
}

/// Force-plate signals against the export (N, N·mm, mm), each value within
/// 1e-4 × max(|expected|, floor), floor = max(1, `floor_fraction` × the plate's largest
/// |expected| force for forces, largest moment for moments and free moments, 0 for the COP).
/// Returns the largest such relative difference per quantity.
fn compare_plates(
    c: &C3d,
    csv: &Csv,
    plates: &[usize],
    floor_fraction: f64,
    what: &str,
) -> [f64; 4] {
    let mut worst = [0.0f64; 4];
    for &p in plates {
        let plate = &c.plates[p];
        assert_eq!(
            plate.n_samples(),
            csv.rows.len(),
            "{what}: plate {} samples",
            p + 1
        );
        let series: [(&str, &Vec<Vec3>, f64); 4] = [
            ("force", &plate.force, 1.0),
            ("moment", &plate.moment, 1000.0),
            ("cop", &plate.cop, 1000.0),
            ("Tz", &plate.free_moment, 1000.0),
        ];
        let cols = |name: &str| -> Vec<usize> {
            ["X", "Y", "Z"]
                .iter()
                .map(|a| csv.column(&format!("p{}_{name}_{a}", p + 1)))
                .collect()
        };
        let peak = |name: &str| {
            let cols = cols(name);
            csv.rows
                .iter()
                .flat_map(|row| {
                    cols.iter()
                        .map(|&k| row[k].unwrap().abs())
                        .collect::<Vec<_>>()
                })
                .fold(0.0, f64::max)
        };
        let floors = [peak("force"), peak("moment"), 0.0, peak("moment")]
            .map(|x| (floor_fraction * x).max(1.0));
        for (q, (name, values, unit)) in series.iter().enumerate() {
            let cols = cols(name);
            let floor = floors[q];
            for (s, row) in csv.rows.iter().enumerate() {
                for k in 0..3 {
                    let expected = row[cols[k]].unwrap();
                    let got = values[s][k] * unit;
                    let rel = (got - expected).abs() / expected.abs().max(floor);
                    worst[q] = worst[q].max(rel);
                    assert!(
                        rel <= 1e-4,
                        "{what}: plate {} {name} axis {k} sample {s}: {got} vs {expected}",
                        p + 1
                    );
                }
            }
        }
    }
    worst
}

#[test]
fn reference_trials_match_the_ezc3d_exports() {
    for name in ["walking2", "walking5"] {
        let Some((bytes, markers, plates)) = trial(name) else {
            return;
        };
        let start = std::time::Instant::now();
        let c = C3d::parse(&bytes, name).unwrap();
        let read_ms = start.elapsed().as_secs_f64() * 1e3;
        assert_eq!(c.processor, Processor::Intel);
        assert_eq!(c.rate_hz, 250.0);
        assert_eq!(c.marker_units, "mm");
        assert_eq!(c.first_frame, 1);
        let (max, gaps) = compare_markers(&c, &markers, 1e-4, name);
        assert!(gaps > 0, "{name}: the trial has gaps");
        let m = c.markers.as_ref().unwrap();
        assert_eq!(m.missing_counts().iter().sum::<usize>(), gaps);
        // Analog: 12 channels at 2000 Hz, 8 samples per frame, one row of the export each.
        let a = &c.analog;
        let expected: Vec<String> = (1..=2)
            .flat_map(|p| ["Fx", "Fy", "Fz", "Mx", "My", "Mz"].map(|l| format!("{l}{p}")))
            .collect();
        assert_eq!(a.labels, expected, "{name}: analog labels");
        assert_eq!(a.units, ["N", "N", "N", "Nmm", "Nmm", "Nmm"].repeat(2));
        assert_eq!(a.rate_hz, 2000.0);
        assert_eq!(a.samples_per_frame, 8);
        assert_eq!(a.n_samples(), 8 * c.n_frames);
        assert_eq!(a.n_samples(), plates.rows.len());
        for ch in 0..a.n_channels() {
            assert_eq!(
                a.channel(ch).len(),
                plates.rows.len(),
                "{name}: channel {ch} samples"
            );
        }
        let t = plates.column("time");
        assert!((plates.rows[1][t].unwrap() - 1.0 / a.rate_hz).abs() < 1e-9);
        // Force platforms.
        assert_eq!(c.plates.len(), 2);
        assert!(c.plates.iter().all(|p| p.kind == 2));
        let mm: Vec<[f64; 3]> = c.plates[0]
            .corners
            .iter()
            .map(|v| [v.x * 1e3, v.y * 1e3, v.z * 1e3])
            .collect();
        for (got, want) in mm.iter().zip([
            [664.6, 379.3, 0.0],
            [664.6, 842.9, 0.0],
            [1172.6, 842.9, 0.0],
            [1172.6, 379.3, 0.0],
        ]) {
            for k in 0..3 {
                assert!(
                    (got[k] - want[k]).abs() < 0.05,
                    "{name}: plate 1 corners {mm:?}"
                );
            }
        }
        let worst = compare_plates(&c, &plates, &[0, 1], 0.0, name);
        eprintln!(
            "{name} ({} bytes, read in {read_ms:.1} ms): {} frames × {} markers, {gaps} gap samples, max marker difference {max:.2e} mm; \
             plates: max relative difference force {:.1e}, moment {:.1e}, COP {:.1e}, free moment {:.1e}",
            bytes.len(),
            c.n_frames,
            m.n_targets(),
            worst[0],
            worst[1],
            worst[2],
            worst[3]
        );
    }
}

// ---------------------------------------------------------------------------------------
// A C3D writer (test side), written from the C3D manual independently of the reader.

/// A parameter value.
#[derive(Clone)]
enum Val {
    /// Strings padded to a common length: dims [length, count].
    Strings(Vec<String>),
    Ints(Vec<usize>, Vec<i16>),
    Floats(Vec<usize>, Vec<f32>),
}

fn ints(v: &[i64]) -> Val {
    Val::Ints(vec![v.len()], v.iter().map(|&x| x as i16).collect())
}

fn floats(v: &[f64]) -> Val {
    Val::Floats(vec![v.len()], v.iter().map(|&x| x as f32).collect())
}

fn int(v: i64) -> Val {
    Val::Ints(vec![], vec![v as i16])
}

fn float(v: f64) -> Val {
    Val::Floats(vec![], vec![v as f32])
}

fn strings(v: &[&str]) -> Val {
    Val::Strings(v.iter().map(|s| s.to_string()).collect())
}

/// What to write: storage, header numbers, parameters and the data (file units).
#[derive(Clone)]
struct Spec {
    /// 84 Intel, 85 DEC, 86 MIPS.
    processor: u8,
    float: bool,
    /// POINT:SCALE magnitude (integer storage).
    scale: f64,
    rate: f64,
    subframes: usize,
    channels: usize,
    /// Per frame, per point: Some(x, y, z) or None (a gap).
    points: Vec<Vec<Option<[f64; 3]>>>,
    /// Per frame: subframes × channels raw values (integers when `float` is false).
    analog: Vec<Vec<f64>>,
    params: Vec<(String, String, Val)>,
}

impl Spec {
    fn set(&mut self, group: &str, name: &str, v: Val) {
        self.params.retain(|(g, n, _)| !(g == group && n == name));
        self.params.push((group.into(), name.into(), v));
    }

    fn remove(&mut self, group: &str, name: &str) {
        self.params.retain(|(g, n, _)| !(g == group && n == name));
    }

    fn u16(&self, v: u16) -> [u8; 2] {
        if self.processor == 86 {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    }

    fn f32(&self, v: f32) -> [u8; 4] {
        match self.processor {
            86 => v.to_be_bytes(),
            85 => {
                // VAX F_floating: 4 × the IEEE value, 16-bit words swapped.
                if v == 0.0 {
                    return [0; 4];
                }
                let b = (v * 4.0).to_le_bytes();
                [b[2], b[3], b[0], b[1]]
            }
            _ => v.to_le_bytes(),
        }
    }

    fn build(&self) -> Vec<u8> {
        let n_points = self.points.first().map_or(0, Vec::len);
        // Parameter records.
        let mut groups: Vec<String> = Vec::new();
        for (g, _, _) in &self.params {
            if !groups.contains(g) {
                groups.push(g.clone());
            }
        }
        let mut rec = Vec::new();
        for (i, g) in groups.iter().enumerate() {
            rec.push(g.len() as u8);
            rec.push((-(i as i8 + 1)) as u8);
            rec.extend(g.as_bytes());
            rec.extend(self.u16(3));
            rec.push(0);
        }
        for (g, name, v) in &self.params {
            let id = groups.iter().position(|x| x == g).unwrap() as u8 + 1;
            let (kind, dims, data): (i8, Vec<usize>, Vec<u8>) = match v {
                Val::Strings(s) => {
                    let len = s.iter().map(String::len).max().unwrap_or(0).max(1);
                    let mut d = Vec::new();
                    for x in s {
                        d.extend(format!("{x:len$}").as_bytes());
                    }
                    (-1, vec![len, s.len()], d)
                }
                Val::Ints(dims, x) => (
                    2,
                    dims.clone(),
                    x.iter().flat_map(|&i| self.u16(i as u16)).collect(),
                ),
                Val::Floats(dims, x) => (
                    4,
                    dims.clone(),
                    x.iter().flat_map(|&f| self.f32(f)).collect(),
                ),
            };
            rec.push(name.len() as u8);
            rec.push(id);
            rec.extend(name.as_bytes());
            rec.extend(self.u16((2 + 1 + 1 + dims.len() + data.len() + 1) as u16));
            rec.push(kind as u8);
            rec.push(dims.len() as u8);
            rec.extend(dims.iter().map(|&d| d as u8));
            rec.extend(data);
            rec.push(0);
        }
        rec.extend([0, 0]);
        let n_blocks = (4 + rec.len()).div_ceil(512);
        let data_start = 2 + n_blocks;
        // Header.
        let mut out = vec![0u8; 512];
        out[0] = 2;
        out[1] = 0x50;
        let mut word = |w: usize, b: [u8; 2]| out[2 * w - 2..2 * w].copy_from_slice(&b);
        word(2, self.u16(n_points as u16));
        word(3, self.u16((self.channels * self.subframes) as u16));
        word(4, self.u16(1));
        word(5, self.u16(self.points.len().max(self.analog.len()) as u16));
        word(9, self.u16(data_start as u16));
        word(10, self.u16(self.subframes as u16));
        let scale = if self.float { -1.0 } else { self.scale as f32 };
        out[12..16].copy_from_slice(&self.f32(scale));
        out[20..24].copy_from_slice(&self.f32(self.rate as f32));
        // Parameter section.
        out.extend([1, 0x50, n_blocks as u8, self.processor]);
        out.extend(rec);
        out.resize((data_start - 1) * 512, 0);
        // Data.
        let frames = self.points.len().max(self.analog.len());
        for f in 0..frames {
            for p in self.points.get(f).map(Vec::as_slice).unwrap_or(&[]) {
                let (xyz, residual) = match p {
                    Some(v) => (*v, 0.0),
                    None => ([0.0; 3], -1.0),
                };
                for x in xyz.into_iter().chain([residual]) {
                    if self.float {
                        out.extend(self.f32(x as f32));
                    } else if x == residual {
                        out.extend(self.u16(x as i16 as u16));
                    } else {
                        out.extend(self.u16((x / self.scale).round() as i16 as u16));
                    }
                }
            }
            for &v in self.analog.get(f).map(Vec::as_slice).unwrap_or(&[]) {
                if self.float {
                    out.extend(self.f32(v as f32));
                } else {
                    out.extend(self.u16(v as i64 as u16));
                }
            }
        }
        out
    }
}

/// The first `frames` frames of a trial as a Spec (Intel floats, file units mm, N, N·mm),
/// with its POINT, ANALOG and FORCE_PLATFORM parameters.
fn spec_of(c: &C3d, frames: usize) -> Spec {
    let m = c.markers.as_ref().unwrap();
    let points = (0..frames)
        .map(|f| {
            m.frame(f)
                .iter()
                .map(|p| p.x.is_finite().then(|| [p.x * 1e3, p.y * 1e3, p.z * 1e3]))
                .collect()
        })
        .collect();
    let a = &c.analog;
    let per_frame = a.samples_per_frame * a.n_channels();
    let analog = (0..frames)
        .map(|f| a.values[f * per_frame..(f + 1) * per_frame].to_vec())
        .collect();
    let names: Vec<&str> = m.names.iter().map(String::as_str).collect();
    let alabels: Vec<&str> = a.labels.iter().map(String::as_str).collect();
    let aunits: Vec<&str> = a.units.iter().map(String::as_str).collect();
    let n = c.plates.len();
    let mut s = Spec {
        processor: 84,
        float: true,
        scale: 0.1,
        rate: c.rate_hz,
        subframes: a.samples_per_frame,
        channels: a.n_channels(),
        points,
        analog,
        params: Vec::new(),
    };
    s.set("POINT", "USED", int(m.n_targets() as i64));
    s.set("POINT", "SCALE", float(-0.1));
    s.set("POINT", "RATE", float(c.rate_hz));
    s.set("POINT", "UNITS", strings(&["mm"]));
    s.set("POINT", "LABELS", strings(&names));
    s.set("ANALOG", "USED", int(a.n_channels() as i64));
    s.set("ANALOG", "LABELS", strings(&alabels));
    s.set("ANALOG", "UNITS", strings(&aunits));
    s.set("ANALOG", "SCALE", floats(&vec![1.0; a.n_channels()]));
    s.set("ANALOG", "OFFSET", ints(&vec![0; a.n_channels()]));
    s.set("ANALOG", "GEN_SCALE", float(1.0));
    s.set("ANALOG", "RATE", float(a.rate_hz));
    s.set("FORCE_PLATFORM", "USED", int(n as i64));
    s.set(
        "FORCE_PLATFORM",
        "TYPE",
        ints(&c.plates.iter().map(|p| p.kind as i64).collect::<Vec<_>>()),
    );
    let corners: Vec<f32> = c
        .plates
        .iter()
        .flat_map(|p| {
            p.corners
                .iter()
                .flat_map(|v| v.iter().map(|x| (x * 1e3) as f32).collect::<Vec<_>>())
        })
        .collect();
    s.set(
        "FORCE_PLATFORM",
        "CORNERS",
        Val::Floats(vec![3, 4, n], corners),
    );
    let origin: Vec<f32> = c
        .plates
        .iter()
        .flat_map(|p| {
            p.origin
                .iter()
                .map(|x| (x * 1e3) as f32)
                .collect::<Vec<_>>()
        })
        .collect();
    s.set("FORCE_PLATFORM", "ORIGIN", Val::Floats(vec![3, n], origin));
    let channels: Vec<i16> = c
        .plates
        .iter()
        .flat_map(|p| p.channels.iter().map(|&ch| ch as i16 + 1))
        .collect();
    s.set("FORCE_PLATFORM", "CHANNEL", Val::Ints(vec![6, n], channels));
    s
}

/// The `rows` first rows of an export.
fn head(csv: &Csv, rows: usize) -> Csv {
    Csv {
        labels: csv.labels.clone(),
        rows: csv.rows[..rows].to_vec(),
    }
}

#[test]
fn the_test_writer_reproduces_the_reference_trial() {
    // The writer's Intel-float copy of walking2 reads back to the same export values, so
    // the variants below differ from it only in what they change.
    let Some((bytes, markers, plates)) = trial("walking2") else {
        return;
    };
    let c = C3d::parse(&bytes, "walking2").unwrap();
    let copy = C3d::parse(&spec_of(&c, c.n_frames).build(), "copy").unwrap();
    compare_markers(&copy, &markers, 1e-4, "copy");
    compare_plates(&copy, &plates, &[0, 1], 0.0, "copy");
}

#[test]
fn dec_mips_and_integer_files_read_the_same_values() {
    let Some((bytes, markers, plates)) = trial("walking2") else {
        return;
    };
    let c = C3d::parse(&bytes, "walking2").unwrap();
    let frames = 300;
    let (markers, plates) = (head(&markers, frames), head(&plates, frames * 8));
    let base = spec_of(&c, frames);
    for (processor, kind) in [
        (84, Processor::Intel),
        (85, Processor::Dec),
        (86, Processor::Mips),
    ] {
        // Floats: the same values as the reference export.
        let mut s = base.clone();
        s.processor = processor;
        let r = C3d::parse(&s.build(), "float").unwrap();
        assert_eq!(r.processor, kind);
        let what = format!("{kind:?} float");
        compare_markers(&r, &markers, 1e-4, &what);
        compare_plates(&r, &plates, &[0, 1], 0.0, &what);

        // Integers: markers × 0.1 mm; analog raw counts with a per-channel SCALE, a signed
        // OFFSET and GEN_SCALE, or UNSIGNED counts around 32768.
        for unsigned in [false, true] {
            let mut s = base.clone();
            s.processor = processor;
            s.float = false;
            s.set("POINT", "SCALE", float(0.1));
            let n = c.analog.n_channels();
            let peak: Vec<f64> = (0..n)
                .map(|ch| {
                    c.analog
                        .channel(ch)
                        .iter()
                        .fold(1.0f64, |m, v| m.max(v.abs()))
                })
                .collect();
            let gen_scale = 2.0;
            let scale: Vec<f64> = peak
                .iter()
                .map(|p| ((p / 20000.0 / gen_scale) as f32) as f64)
                .collect();
            let offset: Vec<i64> = (0..n)
                .map(|ch| {
                    if unsigned {
                        32768
                    } else {
                        100 * ch as i64 - 500
                    }
                })
                .collect();
            for frame in &mut s.analog {
                for (k, v) in frame.iter_mut().enumerate() {
                    let ch = k % n;
                    *v = (*v / (scale[ch] * gen_scale)).round() + offset[ch] as f64;
                }
            }
            s.set("ANALOG", "SCALE", floats(&scale));
            s.set("ANALOG", "GEN_SCALE", float(gen_scale));
            s.set("ANALOG", "OFFSET", ints(&offset));
            if unsigned {
                s.set("ANALOG", "FORMAT", strings(&["UNSIGNED"]));
            }
            let r = C3d::parse(&s.build(), "integer").unwrap();
            let what = format!(
                "{kind:?} integer{}",
                if unsigned { " unsigned" } else { "" }
            );
            compare_markers(&r, &markers, 0.05 + 1e-4, &what);
            for (ch, channel_scale) in scale.iter().enumerate() {
                let (got, want) = (r.analog.channel(ch), c.analog.channel(ch));
                assert_eq!(got.len(), frames * 8);
                for (s, (g, w)) in got.iter().zip(&want).enumerate() {
                    let step = channel_scale * gen_scale;
                    assert!(
                        (g - w).abs() <= 0.5 * step + 1e-9 * w.abs(),
                        "{what}: channel {ch} sample {s}: {g} vs {w} (step {step})"
                    );
                }
            }
        }
    }
}

/// The plate's x, y, z axes in the lab frame.
fn plate_axes(c: &C3d, p: usize) -> [Vec3; 3] {
    let r = &c.plates[p].plate_to_lab;
    [
        r.column(0).into_owned(),
        r.column(1).into_owned(),
        r.column(2).into_owned(),
    ]
}

#[test]
fn force_platform_types_1_3_and_4_reproduce_the_type_2_export() {
    // Plate 1 of walking2 is type 2 (Fx…Mz about the transducer origin, ORIGIN z > 0). The
    // same loads are written as the channels of a type-1, type-3 (Kistler) and type-4
    // (calibration-matrix) plate; each must give the export's force, moment about the centre,
    // COP and free moment. Plate 2 stays type 2.
    let Some((bytes, _, plates)) = trial("walking2") else {
        return;
    };
    let c = C3d::parse(&bytes, "walking2").unwrap();
    let frames = c.n_frames;
    let a = &c.analog;
    let n = a.n_channels();
    let origin = c.plates[0].origin * 1e3; // mm, plate axes, z > 0
    assert!(origin.z > 0.0);
    let r = -origin; // transducer origin → surface centre
    let axes = plate_axes(&c, 0);
    assert!((axes[2].z + 1.0).abs() < 1e-12, "plate z points down");
    // Plate-axes loads of every sample: F (N), M about the origin (N·mm).
    let loads: Vec<(Vec3, Vec3)> = (0..a.n_samples())
        .map(|s| {
            let v = &a.values[s * n..s * n + 6];
            (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
        })
        .collect();
    // Channels of plate 1 per type (replacing analog channels 1–6; type 3 adds two).
    type Encode = Box<dyn Fn(Vec3, Vec3) -> Vec<f64>>;
    let (a3, b3, az0) = (210.0, 320.0, -45.0);
    let cal = nalgebra::Matrix6::<f64>::from_fn(|i, j| {
        let same_block = (i < 3) == (j < 3);
        if i == j {
            1.0 + 0.1 * i as f64
        } else if same_block {
            0.02 * (i as f64 - j as f64)
        } else {
            0.0
        }
    });
    let cal_inv = cal.try_inverse().unwrap();
    let cases: Vec<(i64, Encode, [&str; 8])> = vec![
        (
            1,
            Box::new(move |f: Vec3, m: Vec3| {
                let mc = m + f.cross(&r);
                let cop = Vec3::new(-mc.y / f.z, mc.x / f.z, 0.0);
                let tz = mc.z + f.cross(&cop).z;
                vec![f.x, f.y, f.z, cop.x, cop.y, tz]
            }),
            ["N", "N", "N", "mm", "mm", "Nmm", "", ""],
        ),
        (
            3,
            Box::new(move |f: Vec3, m: Vec3| {
                // Moment about the sensor-plane centre, az0 below the surface.
                let mo = m + f.cross(&r) - f.cross(&Vec3::new(0.0, 0.0, az0));
                let (s, p, q) = (f.z, mo.x / b3, mo.y / a3);
                vec![
                    f.x / 2.0 - mo.z / (2.0 * b3),
                    f.x / 2.0 + mo.z / (2.0 * b3),
                    f.y / 2.0,
                    f.y / 2.0,
                    (s + p - q) / 4.0,
                    (s + p + q) / 4.0,
                    (s - p + q) / 4.0,
                    (s - p - q) / 4.0,
                ]
            }),
            ["N"; 8],
        ),
        (
            4,
            Box::new(move |f: Vec3, m: Vec3| {
                let raw = cal_inv * nalgebra::Vector6::new(f.x, f.y, f.z, m.x, m.y, m.z);
                raw.iter().copied().collect()
            }),
            ["V"; 8],
        ),
    ];
    for (kind, encode, units) in cases {
        let width = if kind == 3 { 8 } else { 6 };
        let mut s = spec_of(&c, frames);
        s.points = Vec::new();
        s.set("POINT", "USED", int(0));
        s.remove("POINT", "LABELS");
        s.channels = width + 6;
        s.analog = (0..frames)
            .map(|f| {
                (0..8)
                    .flat_map(|k| {
                        let sample = f * 8 + k;
                        let (force, moment) = loads[sample];
                        let mut row = encode(force, moment);
                        row.extend_from_slice(&a.values[sample * n + 6..sample * n + 12]);
                        row
                    })
                    .collect()
            })
            .collect();
        let mut labels: Vec<String> = (1..=width).map(|k| format!("plate1_{k}")).collect();
        labels.extend(a.labels[6..].iter().cloned());
        let mut all_units: Vec<&str> = units[..width].to_vec();
        all_units.extend(a.units[6..].iter().map(String::as_str));
        s.set("ANALOG", "USED", int(s.channels as i64));
        s.set("ANALOG", "LABELS", Val::Strings(labels));
        s.set("ANALOG", "UNITS", strings(&all_units));
        s.set("ANALOG", "SCALE", floats(&vec![1.0; s.channels]));
        s.set("ANALOG", "OFFSET", ints(&vec![0; s.channels]));
        s.set("FORCE_PLATFORM", "TYPE", ints(&[kind, 2]));
        let mut channel: Vec<i16> = (1..=8).collect();
        channel.extend((width as i16 + 1..=width as i16 + 6).chain([0, 0]));
        s.set("FORCE_PLATFORM", "CHANNEL", Val::Ints(vec![8, 2], channel));
        let mut o: Vec<f32> = if kind == 3 {
            vec![a3 as f32, b3 as f32, az0 as f32]
        } else {
            origin.iter().map(|&x| x as f32).collect()
        };
        o.extend(c.plates[1].origin.iter().map(|x| (x * 1e3) as f32));
        s.set("FORCE_PLATFORM", "ORIGIN", Val::Floats(vec![3, 2], o));
        if kind == 4 {
            let mut v: Vec<f32> = (0..36).map(|k| cal[(k % 6, k / 6)] as f32).collect();
            v.extend([0.0; 36]);
            s.set(
                "FORCE_PLATFORM",
                "CAL_MATRIX",
                Val::Floats(vec![6, 6, 2], v),
            );
        }
        let r = C3d::parse(&s.build(), &format!("type {kind}")).unwrap();
        assert!(r.markers.is_none());
        assert_eq!(r.plates[0].kind, kind as u8);
        // The synthetic channels are stored as f32: differences up to about 1e-7 of the
        // largest load remain, hence the floor of 1e-4 × (1e-4 × the largest load).
        let worst = compare_plates(&r, &plates, &[0, 1], 1e-4, &format!("type {kind}"));
        eprintln!(
            "type {kind}: max relative difference force {:.1e}, moment {:.1e}, COP {:.1e}, free moment {:.1e}",
            worst[0], worst[1], worst[2], worst[3]
        );
    }
}

#[test]
fn lab_to_opensim_is_minus_90_degrees_about_x_and_the_grf_table_uses_it() {
    let up = c3d::lab_to_opensim(&Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(up, Vec3::new(0.0, 1.0, 0.0), "lab z (up) → OpenSim y (up)");
    assert_eq!(
        c3d::lab_to_opensim(&Vec3::new(1.0, 0.0, 0.0)),
        Vec3::new(1.0, 0.0, 0.0)
    );
    assert_eq!(
        c3d::lab_to_opensim(&Vec3::new(0.0, 1.0, 0.0)),
        Vec3::new(0.0, 0.0, -1.0)
    );
    let Some((bytes, _, _)) = trial("walking2") else {
        return;
    };
    let c = C3d::parse(&bytes, "walking2").unwrap();
    let m = c.markers.as_ref().unwrap();
    let rotated = c3d::markers_to_opensim(m);
    rotated.validate().unwrap();
    assert_eq!(rotated.missing_counts(), m.missing_counts());
    let f = m.n_frames() / 2;
    let heel = m.index("RCAL").unwrap();
    let (p, q) = (m.frame(f)[heel], rotated.frame(f)[heel]);
    assert_eq!(q, Vec3::new(p.x, p.z, -p.y));

    let t = c.ground_reactions(20.0).unwrap();
    assert_eq!(t.labels.len(), 18);
    assert_eq!(t.n_rows(), c.analog.n_samples());
    assert_eq!(t.time[1], 1.0 / 2000.0);
    let vy = t.column("plate1_force_vy").unwrap();
    let (s, peak) = vy
        .iter()
        .enumerate()
        .fold((0, 0.0), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
    let plate = &c.plates[0];
    // The force as ezc3d reports it: the reaction on the subject, up (+y) in stance.
    assert!(peak > 500.0, "stance peak {peak} N");
    assert_eq!(peak, plate.force[s].z);
    let cop = plate.cop[s];
    for (col, want) in [
        ("plate1_force_px", cop.x),
        ("plate1_force_py", cop.z),
        ("plate1_force_pz", -cop.y),
    ] {
        assert_eq!(
            t.value(s, t.column_index(col).unwrap()),
            Some(want),
            "{col}"
        );
    }
    assert_eq!(
        t.column("plate1_torque_y").unwrap()[s],
        plate.free_moment[s].z
    );
    // Swing: below the threshold everything is 0.
    let swing = (0..t.n_rows())
        .find(|&k| plate.force[k].z.abs() < 20.0)
        .unwrap();
    let row = t.row(swing).unwrap();
    assert!(row[..9].iter().all(|&v| v == 0.0));
    assert!(matches!(
        c.ground_reactions(0.0),
        Err(Error::InvalidArgument { .. })
    ));
}

// ---------------------------------------------------------------------------------------
// Bad input

/// The reader's result, or the case recorded in `panics` if it panicked.
fn parse_guarded(bytes: &[u8], case: &str, panics: &mut Vec<String>) -> Option<Result<C3d, Error>> {
    match catch_unwind(AssertUnwindSafe(|| C3d::parse(bytes, case))) {
        Ok(r) => Some(r),
        Err(_) => {
            panics.push(case.to_string());
            None
        }
    }
}

/// (file, location, message) of a motion error.
fn motion_error(r: Result<C3d, Error>, case: &str) -> (String, String, String) {
    match r {
        Err(Error::Motion {
            file,
            location,
            message,
        }) => (file, location, message),
        Err(e) => panic!("{case}: expected a motion error, got {e}"),
        Ok(_) => panic!("{case}: read without error"),
    }
}

#[test]
fn truncated_files_are_errors_naming_the_incomplete_frame() {
    let Some((bytes, _, _)) = trial("walking2") else {
        return;
    };
    let data_start = (u16::from_le_bytes([bytes[16], bytes[17]]) as usize - 1) * 512;
    let frame_bytes = 44 * 16 + 96 * 4;
    assert_eq!(data_start + 1249 * frame_bytes, bytes.len());
    let mut cuts: Vec<usize> = (0..bytes.len()).step_by(3331).collect();
    cuts.extend([
        1,
        2,
        511,
        512,
        513,
        515,
        516,
        1024,
        data_start - 1,
        data_start,
        data_start + 1,
        bytes.len() - 1,
    ]);
    let mut panics = Vec::new();
    for cut in cuts {
        let case = format!("walking2 cut to {cut} bytes");
        let Some(r) = parse_guarded(&bytes[..cut], &case, &mut panics) else {
            continue;
        };
        let (file, location, message) = motion_error(r, &case);
        assert_eq!(file, case);
        if cut >= data_start {
            let frame = (cut - data_start) / frame_bytes;
            assert_eq!(location, format!("frame {frame}"), "{case}: {message}");
            assert!(message.contains("truncated"), "{case}: {message}");
        } else {
            assert!(
                location == "header" || location.starts_with("parameter"),
                "{case}: {location}: {message}"
            );
        }
    }
    assert!(panics.is_empty(), "the reader panicked on: {panics:?}");
}

#[test]
fn mutated_headers_parameters_and_data_never_panic() {
    // A 20-frame copy of walking2 with its own header and parameter section (header word 5
    // set to 20, the data cut after frame 20), then every byte of the header and parameter
    // section changed in 12 ways, and 3000 random multi-byte mutations of the whole file.
    let Some((bytes, _, _)) = trial("walking2") else {
        return;
    };
    let full = C3d::parse(&bytes, "walking2").unwrap();
    let data_start = (u16::from_le_bytes([bytes[16], bytes[17]]) as usize - 1) * 512;
    let frames = 20;
    let mut small = bytes[..data_start + frames * (44 * 16 + 96 * 4)].to_vec();
    small[8..10].copy_from_slice(&(frames as u16).to_le_bytes());
    let s = C3d::parse(&small, "small").unwrap();
    assert_eq!(s.n_frames, frames);
    let (a, b) = (s.markers.as_ref().unwrap(), full.markers.as_ref().unwrap());
    for (p, q) in a.positions.iter().zip(&b.positions) {
        assert!(p == q || (p.x.is_nan() && q.x.is_nan()));
    }
    let mut panics = Vec::new();
    let (mut ok, mut err) = (0usize, 0usize);
    let mut check =
        |m: &[u8], case: String, panics: &mut Vec<String>| match parse_guarded(m, &case, panics) {
            Some(Ok(c)) => {
                ok += 1;
                if let Some(mk) = &c.markers {
                    mk.validate()
                        .unwrap_or_else(|e| panic!("{case}: read an invalid motion: {e}"));
                }
                for p in &c.plates {
                    assert_eq!(p.n_samples(), c.analog.n_samples(), "{case}");
                }
            }
            Some(Err(e)) => {
                err += 1;
                assert!(
                    matches!(e, Error::Motion { ref file, .. } if *file == case),
                    "{case}: {e}"
                );
            }
            None => {}
        };
    // Every byte in release builds (about 80,000 files, seconds); every 7th in debug builds,
    // whose overflow checks make each read about 40 times slower.
    let stride = if cfg!(debug_assertions) { 7 } else { 1 };
    for at in (0..data_start).step_by(stride) {
        for bit in 0..8 {
            let mut m = small.clone();
            m[at] ^= 1 << bit;
            check(&m, format!("byte {at} bit {bit} flipped"), &mut panics);
        }
        for v in [0x00, 0xff, 0x7f, 0x80] {
            let mut m = small.clone();
            m[at] = v;
            check(&m, format!("byte {at} set to {v:#04x}"), &mut panics);
        }
    }
    let mut rng = common::Rng::new(10);
    for k in 0..3000 {
        let mut m = small.clone();
        for _ in 0..1 + rng.below(8) {
            let at = rng.below(m.len());
            m[at] = rng.next_u64() as u8;
        }
        if k % 10 == 0 {
            m.truncate(rng.below(m.len()));
        }
        check(&m, format!("random mutation {k}"), &mut panics);
    }
    for k in 0..200 {
        let len = rng.below(4096);
        let mut m: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
        if len > 1 {
            m[1] = 0x50;
            m[0] = 2;
        }
        check(&m, format!("random bytes {k}"), &mut panics);
    }
    eprintln!(
        "mutated files: {ok} read (valid), {err} refused with an error, {} panics",
        panics.len()
    );
    assert!(
        panics.is_empty(),
        "the reader panicked on {} files, e.g. {:?}",
        panics.len(),
        &panics[..panics.len().min(10)]
    );
    assert!(
        err > 1000,
        "most mutations of the header and parameters are refused"
    );
}

#[test]
fn inconsistent_files_are_errors_naming_file_and_place() {
    let Some((bytes, _, _)) = trial("walking2") else {
        return;
    };
    let c = C3d::parse(&bytes, "walking2").unwrap();
    let base = spec_of(&c, 10);
    C3d::parse(&base.build(), "base").unwrap();
    let labels: Vec<String> = c.markers.as_ref().unwrap().names.clone();
    type Edit = Box<dyn Fn(&mut Spec) -> Option<Vec<u8>>>;
    let cases: Vec<(&str, Edit, &str, &str)> = vec![
        (
            "not a C3D",
            Box::new(|s: &mut Spec| {
                let mut b = s.build();
                b[1] = 0;
                Some(b)
            }),
            "header",
            "not a C3D file",
        ),
        (
            "processor 87",
            Box::new(|s: &mut Spec| {
                let mut b = s.build();
                b[515] = 87;
                Some(b)
            }),
            "parameter section",
            "processor type 87",
        ),
        (
            "data start inside the parameters",
            Box::new(|s: &mut Spec| {
                let mut b = s.build();
                b[16] = 2;
                Some(b)
            }),
            "header",
            "data section starts at block 2",
        ),
        (
            "POINT:USED",
            Box::new(|s: &mut Spec| {
                s.set("POINT", "USED", int(43));
                None
            }),
            "parameter POINT:USED",
            "header says 44",
        ),
        (
            "ANALOG:USED",
            Box::new(|s: &mut Spec| {
                s.set("ANALOG", "USED", int(11));
                None
            }),
            "parameter ANALOG:USED",
            "holds 12",
        ),
        (
            "ANALOG:RATE",
            Box::new(|s: &mut Spec| {
                s.set("ANALOG", "RATE", float(1000.0));
                None
            }),
            "parameter ANALOG:RATE",
            "2000 Hz",
        ),
        (
            "POINT:RATE",
            Box::new(|s: &mut Spec| {
                s.set("POINT", "RATE", float(120.0));
                None
            }),
            "parameter POINT:RATE",
            "header says 250",
        ),
        (
            "POINT:UNITS missing",
            Box::new(|s: &mut Spec| {
                s.remove("POINT", "UNITS");
                None
            }),
            "parameter POINT:UNITS",
            "missing",
        ),
        (
            "POINT:UNITS furlong",
            Box::new(|s: &mut Spec| {
                s.set("POINT", "UNITS", strings(&["furlong"]));
                None
            }),
            "parameter POINT:UNITS",
            "not a length unit",
        ),
        (
            "POINT:LABELS short",
            Box::new(|s: &mut Spec| {
                s.set("POINT", "LABELS", strings(&["A", "B"]));
                None
            }),
            "parameter POINT:LABELS",
            "2 labels for 44 points",
        ),
        (
            "ANALOG:SCALE missing",
            Box::new(|s: &mut Spec| {
                s.remove("ANALOG", "SCALE");
                None
            }),
            "parameter ANALOG:SCALE",
            "missing",
        ),
        (
            "ANALOG:OFFSET short",
            Box::new(|s: &mut Spec| {
                s.set("ANALOG", "OFFSET", ints(&[0; 5]));
                None
            }),
            "parameter ANALOG:OFFSET",
            "5 values for 12 channels",
        ),
        (
            "SCALE as text",
            Box::new(|s: &mut Spec| {
                s.set("ANALOG", "SCALE", strings(&["1"]));
                None
            }),
            "parameter ANALOG:SCALE",
            "text",
        ),
        (
            "plate type 5",
            Box::new(|s: &mut Spec| {
                s.set("FORCE_PLATFORM", "TYPE", ints(&[5, 2]));
                None
            }),
            "force platform 1",
            "TYPE 5 is not supported",
        ),
        (
            "more plates than channels",
            Box::new(|s: &mut Spec| {
                s.set("FORCE_PLATFORM", "USED", int(13));
                None
            }),
            "parameter FORCE_PLATFORM:USED",
            "13 platforms, but the file has 12 analog channels",
        ),
        (
            "plate channel 13",
            Box::new(|s: &mut Spec| {
                s.set(
                    "FORCE_PLATFORM",
                    "CHANNEL",
                    Val::Ints(vec![6, 2], vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13]),
                );
                None
            }),
            "force platform 2",
            "13, outside the 12 analog channels",
        ),
        (
            "type 4 without CAL_MATRIX",
            Box::new(|s: &mut Spec| {
                s.set("FORCE_PLATFORM", "TYPE", ints(&[4, 2]));
                None
            }),
            "force platform 1",
            "CAL_MATRIX",
        ),
        (
            "collinear corners",
            Box::new(|s: &mut Spec| {
                s.set(
                    "FORCE_PLATFORM",
                    "CORNERS",
                    Val::Floats(
                        vec![3, 4, 2],
                        [
                            [0.0, 0.0, 0.0],
                            [1.0, 0.0, 0.0],
                            [2.0, 0.0, 0.0],
                            [3.0, 0.0, 0.0],
                        ]
                        .concat()
                        .repeat(2),
                    ),
                );
                None
            }),
            "force platform 1",
            "do not span a plane",
        ),
        (
            "CORNERS missing",
            Box::new(|s: &mut Spec| {
                s.remove("FORCE_PLATFORM", "CORNERS");
                None
            }),
            "parameter FORCE_PLATFORM:CORNERS",
            "missing",
        ),
        (
            "moment unit",
            Box::new(|s: &mut Spec| {
                let mut u = vec!["N"; 12];
                u[3] = "V";
                s.set("ANALOG", "UNITS", strings(&u));
                None
            }),
            "force platform 1",
            "not a moment unit",
        ),
        (
            "duplicate label",
            Box::new({
                let l = labels.clone();
                move |s: &mut Spec| {
                    let mut l = l.clone();
                    l[1] = l[0].clone();
                    s.set("POINT", "LABELS", Val::Strings(l));
                    None
                }
            }),
            "target \"RTH1\"",
            "duplicate",
        ),
        (
            "infinite marker",
            Box::new(|s: &mut Spec| {
                s.points[3][5] = Some([f64::INFINITY, 0.0, 0.0]);
                None
            }),
            "frame 3, marker \"LTB1\"",
            "not finite",
        ),
        (
            "marker a thousand kilometres away",
            Box::new(|s: &mut Spec| {
                s.points[2][4] = Some([0.0, 2e9, 0.0]); // mm
                None
            }),
            "frame 2, marker \"LTH3\"",
            "beyond ±1e6 m",
        ),
        (
            "infinite analog",
            Box::new(|s: &mut Spec| {
                s.analog[4][7] = f64::INFINITY;
                None
            }),
            "frame 4, analog channel \"Fy2\"",
            "not finite",
        ),
        (
            "last before first frame",
            Box::new(|s: &mut Spec| {
                let mut b = s.build();
                b[8..10].copy_from_slice(&0u16.to_le_bytes());
                Some(b)
            }),
            "header",
            "precedes first frame",
        ),
    ];
    for (case, edit, location, message) in cases {
        let mut s = base.clone();
        let b = edit(&mut s).unwrap_or_else(|| s.build());
        let mut panics = Vec::new();
        let r = parse_guarded(&b, case, &mut panics).unwrap_or_else(|| panic!("{case}: panicked"));
        let (file, loc, msg) = motion_error(r, case);
        assert_eq!(file, case);
        assert!(
            loc.starts_with(location),
            "{case}: location {loc:?}, expected {location:?} ({msg})"
        );
        assert!(
            msg.contains(message),
            "{case}: message {msg:?} lacks {message:?}"
        );
    }
    let missing = std::path::Path::new("/nonexistent/trial.c3d");
    assert!(matches!(C3d::read(missing), Err(Error::Io { ref path, .. }) if path == missing));
}

#[test]
fn markers_all_at_the_origin_are_refused_not_fitted() {
    // Before: a trial whose markers all sit at the origin was read, and `ik` fitted it with
    // 123 mm errors and called the clip "ok".
    let Some((bytes, _, _)) = trial("walking2") else {
        return;
    };
    let c = C3d::parse(&bytes, "walking2").unwrap();
    let mut spec = spec_of(&c, 20);
    for frame in &mut spec.points {
        for p in frame.iter_mut() {
            *p = Some([0.0, 0.0, 0.0]);
        }
    }
    let dir = std::env::temp_dir().join(format!("musculo-c3d-origin-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("origin.c3d");
    std::fs::write(&path, spec.build()).unwrap();
    let e = musculo::motion::read(&path, None, &Default::default()).unwrap_err();
    std::fs::remove_dir_all(&dir).ok();
    let (file, location, message) = motion_error(Err(e), "origin");
    assert!(file.ends_with("origin.c3d"), "{file}");
    assert_eq!(location, "POINT");
    assert!(message.contains("same point"), "{message}");
    // The unedited trial still reads (its markers span a walking person).
    let spec = spec_of(&c, c.n_frames);
    let path = dir.join("walking.c3d");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(&path, spec.build()).unwrap();
    let read = musculo::motion::read(&path, None, &Default::default());
    std::fs::remove_dir_all(&dir).ok();
    let spread = read.unwrap().marker_spread().unwrap();
    assert!((0.2..2.5).contains(&spread), "{spread}");
}
