//! The motion readers never panic, whatever the bytes: truncated, byte-flipped, line-dropped
//! and spliced versions of the reference BVH and `.npy` files each give `Ok` or `Err`.

mod common;

use common::{Rng, reference_file};
use musculo::motion::bvh::{self, Bvh, BvhOptions, CMU_UNIT_M};
use musculo::motion::{LengthUnit, humanml3d, kit, npy};

/// Mutations of `bytes`: every truncation on a coarse grid, then random byte flips, deleted
/// and duplicated byte ranges, and random bytes inserted.
fn mutations(bytes: &[u8], rng: &mut Rng, count: usize) -> Vec<Vec<u8>> {
    let n = bytes.len();
    let mut out: Vec<Vec<u8>> = (0..40).map(|k| bytes[..n * k / 40].to_vec()).collect();
    out.extend((0..32).map(|k| bytes[..k.min(n)].to_vec()));
    for _ in 0..count {
        let mut b = bytes.to_vec();
        match rng.below(4) {
            0 => {
                for _ in 0..1 + rng.below(8) {
                    let i = rng.below(b.len());
                    b[i] = rng.next_u64() as u8;
                }
            }
            1 => {
                let i = rng.below(b.len());
                let j = (i + 1 + rng.below(200)).min(b.len());
                b.drain(i..j);
            }
            2 => {
                let i = rng.below(b.len());
                let j = (i + 1 + rng.below(200)).min(b.len());
                let piece = b[i..j].to_vec();
                let at = rng.below(b.len());
                b.splice(at..at, piece);
            }
            _ => {
                let at = rng.below(b.len());
                let junk: Vec<u8> = (0..1 + rng.below(16))
                    .map(|_| rng.next_u64() as u8)
                    .collect();
                b.splice(at..at, junk);
            }
        }
        out.push(b);
    }
    out
}

/// Bytes that look like a header field: digits, signs, separators and keywords.
fn bvh_word_mutations(text: &str, rng: &mut Rng, count: usize) -> Vec<String> {
    let words = [
        "nan",
        "inf",
        "-1",
        "0",
        "1e308",
        "99999999999",
        "{",
        "}",
        "JOINT",
        "End",
        "Site",
        "ROOT",
        "MOTION",
        "CHANNELS",
        "OFFSET",
        "Frames:",
        "Frame",
        "Time:",
        "\n",
        "",
    ];
    let lines: Vec<&str> = text.lines().collect();
    (0..count)
        .map(|_| {
            let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
            let i = rng.below(l.len().min(200));
            let mut parts: Vec<String> = l[i].split_whitespace().map(String::from).collect();
            let k = rng.below(parts.len() + 1);
            let w = words[rng.below(words.len())].to_string();
            if k < parts.len() && rng.below(2) == 0 {
                parts[k] = w;
            } else {
                parts.insert(k.min(parts.len()), w);
            }
            l[i] = parts.join(" ");
            if rng.below(3) == 0 {
                let j = rng.below(l.len());
                l.remove(j);
            }
            l.join("\n")
        })
        .collect()
}

#[test]
fn bvh_reader_never_panics_on_mutated_files() {
    let mut rng = Rng::new(0x05ee_db1d);
    let mut results = [0usize; 2];
    for file in ["bvh/131_01.bvh", "bvh/131_03.bvh"] {
        let Some(path) = reference_file(file) else {
            return;
        };
        let bytes = std::fs::read(&path).unwrap();
        // Keep the hierarchy and the first 20 frames: mutations then reach every part.
        let text = String::from_utf8(bytes).unwrap();
        let keep: usize = text.split_inclusive('\n').take(207).map(str::len).sum();
        let text = text[..keep]
            .replace("Frames: 994", "Frames: 20")
            .replace("Frames: 1102", "Frames: 20");
        let options = BvhOptions {
            unit: LengthUnit::Custom(CMU_UNIT_M),
            end_sites: true,
            ..Default::default()
        };
        assert!(bvh::parse(&text, file, &options).is_ok());
        for m in mutations(text.as_bytes(), &mut rng, 300) {
            let Ok(s) = std::str::from_utf8(&m) else {
                continue;
            };
            let r = Bvh::parse(s, file).and_then(|b| b.to_motion(&options));
            results[r.is_ok() as usize] += 1;
        }
        for s in bvh_word_mutations(&text, &mut rng, 300) {
            let r = Bvh::parse(&s, file).and_then(|b| b.to_motion(&options));
            results[r.is_ok() as usize] += 1;
        }
    }
    eprintln!(
        "BVH mutations: {} errors, {} still valid, no panic",
        results[0], results[1]
    );
    assert!(results[0] > 500);
}

#[test]
fn npy_and_dataset_readers_never_panic_on_mutated_files() {
    let mut rng = Rng::new(0x00c0_ffee);
    let mut results = [0usize; 2];
    for file in [
        "humanml3d/new_joints_012314.npy",
        "humanml3d/new_joint_vecs_012314.npy",
        "humanml3d/Mean.npy",
    ] {
        let Some(path) = reference_file(file) else {
            return;
        };
        let bytes = std::fs::read(&path).unwrap();
        for m in mutations(&bytes, &mut rng, 300) {
            let r = npy::parse_array_as_f64(&m, file);
            if let Ok(a) = &r {
                let _ = humanml3d::from_array(a.view(), file, &humanml3d::Options::default());
                let _ = kit::from_array(a.view(), file, &kit::Options::default());
            }
            let _ = npy::parse_array::<f32>(&m, file);
            results[r.is_ok() as usize] += 1;
        }
    }
    eprintln!(
        ".npy mutations: {} errors, {} still readable, no panic",
        results[0], results[1]
    );
    assert!(results[0] > 300);
}

#[test]
fn npz_reader_never_panics_on_mutated_archives() {
    let dir = std::env::temp_dir().join(format!("musculo-motion-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let a = ndarray::ArrayD::<f32>::from_shape_fn(ndarray::IxDyn(&[30, 22, 3]), |i| {
        (i[0] + i[1] + i[2]) as f32
    });
    let mut rng = Rng::new(7);
    let mut errors = 0;
    for compressed in [false, true] {
        let path = dir.join("a.npz");
        npy::write_npz(
            &path,
            &[("joint_pos", a.view()), ("q", a.view())],
            compressed,
        )
        .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        for (k, m) in mutations(&bytes, &mut rng, 150).into_iter().enumerate() {
            let p = dir.join(format!("m{k}.npz"));
            std::fs::write(&p, &m).unwrap();
            errors += npy::read_npz_as_f64(&p).is_err() as usize;
            let _ = std::fs::remove_file(&p);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(errors > 100, "{errors}");
}
