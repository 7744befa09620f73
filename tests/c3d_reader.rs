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
        let labels = lines.next().unwrap().split(',').map(str::to_string).collect();
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
        self.labels.iter().position(|l| l == label).unwrap_or_else(|| panic!("no column {label}"))
    }
}

/// The trial, its marker export and its force-plate export, or None (skipped).
fn trial(name: &str) -> Option<(Vec<u8>, Csv, Csv)> {
    let c3d = reference_file(&format!("c3d/{name}.c3d"))?;
    let markers = reference_file(&format!("c3d/{name}_markers.csv"))?;
    let plates = reference_file(&format!("c3d/{name}_forceplates.csv"))?;
    Some((std::fs::read(c3d).unwrap(), Csv::read(&markers), Csv::read(&plates)))
}

/// Markers (mm) against the export: same labels in the same order, same frames and times,
/// gaps at exactly the same samples, coordinates within `tol` mm. Returns the largest
/// difference and the number of gap samples.
fn compare_markers(c: &C3d, csv: &Csv, tol: f64, what: &str) -> (f64, usize) {
    let m = c.markers.as_ref().expect("markers");
    let labels: Vec<String> = csv.labels[2..].iter().step_by(3).map(|l| l.trim_end_matches("_X").to_string()).collect();
    assert_eq!(m.names, labels, "{what}: marker labels");
    assert_eq!(m.n_frames(), csv.rows.len(), "{what}: frames");
    let (mut max, mut gaps) = (0.0f64, 0);
    for (f, row) in csv.rows.iter().enumerate() {
        assert_eq!(row[0], Some((f + 1) as f64), "{what}: frame column");
        assert!((m.time[f] - row[1].unwrap()).abs() <= 5e-7, "{what}: time of frame {f}");
        for (i, p) in m.frame(f).iter().enumerate() {
            let expected = &row[2 + 3 * i..5 + 3 * i];
            if expected.iter().all(Option::is_none) {
                gaps += 1;
                assert!(p.iter().all(|x| x.is_nan()), "{what}: frame {f} {} should be a gap", m.names[i]);
                continue;
            }
            assert!(p.iter().all(|x| x.is_finite()), "{what}: frame {f} {} is a gap, not in the export", m.names[i]);
            for k in 0..3 {
                let d = (p[k] * 1000.0 - expected[k].unwrap()).abs();
                max = max.max(d);
                assert!(d <= tol, "{what}: frame {f} {} axis {k}: {} mm vs {:?}", m.names[i], p[k] * 1000.0, expected[k]);
            }
        }
    }
    (max, gaps)
}

/// Force-plate signals against the export (N, N·mm, mm), each value within
/// 1e-4 × max(|expected|, 1). Returns the largest relative difference per quantity.
fn compare_plates(c: &C3d, csv: &Csv, plates: &[usize], what: &str) -> [f64; 4] {
    let mut worst = [0.0f64; 4];
    for &p in plates {
        let plate = &c.plates[p];
        assert_eq!(plate.n_samples(), csv.rows.len(), "{what}: plate {} samples", p + 1);
        let series: [(&str, &Vec<Vec3>, f64); 4] = [
            ("force", &plate.force, 1.0),
            ("moment", &plate.moment, 1000.0),
            ("cop", &plate.cop, 1000.0),
            ("Tz", &plate.free_moment, 1000.0),
        ];
        for (q, (name, values, unit)) in series.iter().enumerate() {
            let cols: Vec<usize> = ["X", "Y", "Z"].iter().map(|a| csv.column(&format!("p{}_{name}_{a}", p + 1))).collect();
            for (s, row) in csv.rows.iter().enumerate() {
                for k in 0..3 {
                    let expected = row[cols[k]].unwrap();
                    let got = values[s][k] * unit;
                    let rel = (got - expected).abs() / expected.abs().max(1.0);
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
        let Some((bytes, markers, plates)) = trial(name) else { return };
        let c = C3d::parse(&bytes, name).unwrap();
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
            assert_eq!(a.channel(ch).len(), plates.rows.len(), "{name}: channel {ch} samples");
        }
        let t = plates.column("time");
        assert!((plates.rows[1][t].unwrap() - 1.0 / a.rate_hz).abs() < 1e-9);
        // Force platforms.
        assert_eq!(c.plates.len(), 2);
        assert!(c.plates.iter().all(|p| p.kind == 2));
        let mm: Vec<[f64; 3]> = c.plates[0].corners.iter().map(|v| [v.x * 1e3, v.y * 1e3, v.z * 1e3]).collect();
        for (got, want) in mm.iter().zip([[664.6, 379.3, 0.0], [664.6, 842.9, 0.0], [1172.6, 842.9, 0.0], [1172.6, 379.3, 0.0]]) {
            for k in 0..3 {
                assert!((got[k] - want[k]).abs() < 0.05, "{name}: plate 1 corners {mm:?}");
            }
        }
        let worst = compare_plates(&c, &plates, &[0, 1], name);
        eprintln!(
            "{name}: {} frames × {} markers, {gaps} gap samples, max marker difference {max:.2e} mm; \
             plates: max relative difference force {:.1e}, moment {:.1e}, COP {:.1e}, free moment {:.1e}",
            c.n_frames,
            m.n_targets(),
            worst[0],
            worst[1],
            worst[2],
            worst[3]
        );
    }
}
