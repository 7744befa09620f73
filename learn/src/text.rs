//! Text conditions: the captions of a training set and their vectors.
//!
//! Two sources of a caption's vector e (E values):
//! - **built-in**: a bag of words hashed into V buckets — each lower-cased word w of the caption
//!   adds 1/|words| to bucket FNV-1a(w) mod V — which the diffusion model's first layer maps to
//!   its width, so the word vectors are learned with the denoiser (no pretrained weights exist
//!   on a machine without a network). E = V.
//! - **precomputed**: one vector per clip from an `.npz` with an array per clip name (e.g. CLIP's
//!   512 values, as the papers use), and one `.npy` per prompt when generating.
//!
//! Captions of a training set: `texts.json` ({"clip": "caption", …}) in the data folder, or
//! HumanML3D's `texts/<clip>.txt` (the caption is the text before the first `#` of its first
//! line); a clip without either is captioned by its name with `_` and `-` read as spaces.

use crate::error::{LearnError, Result};
use std::path::{Path, PathBuf};

/// V, the buckets of the built-in bag of words.
pub const BUCKETS: usize = 512;

/// The built-in vector of `caption` (module docs): V values summing to 1 (all 0 for a caption
/// without words).
pub fn bag_of_words(caption: &str) -> Vec<f32> {
    let words: Vec<String> = caption
        .split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(|w| w.to_lowercase())
        .collect();
    let mut v = vec![0.0f32; BUCKETS];
    for w in &words {
        v[(fnv1a(w.as_bytes()) % BUCKETS as u64) as usize] += 1.0 / words.len() as f32;
    }
    v
}

/// FNV-1a, 64 bits.
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The caption of clip `name` whose tensor file is `file`, from the folders `roots` (module
/// docs).
pub fn caption(name: &str, file: &Path, roots: &[PathBuf]) -> Result<String> {
    let mut folders: Vec<PathBuf> = roots.to_vec();
    if let Some(parent) = file.parent() {
        folders.push(parent.to_path_buf());
    }
    for folder in &folders {
        let json = folder.join("texts.json");
        if json.is_file() {
            let text = std::fs::read_to_string(&json).map_err(|e| LearnError::File {
                path: json.clone(),
                message: e.to_string(),
            })?;
            let map: serde_json::Value =
                serde_json::from_str(&text).map_err(|e| LearnError::File {
                    path: json.clone(),
                    message: e.to_string(),
                })?;
            if let Some(c) = map[name].as_str() {
                return Ok(c.to_string());
            }
        }
        let txt = folder.join("texts").join(format!("{name}.txt"));
        if txt.is_file() {
            let text = std::fs::read_to_string(&txt).map_err(|e| LearnError::File {
                path: txt.clone(),
                message: e.to_string(),
            })?;
            if let Some(line) = text.lines().find(|l| !l.trim().is_empty()) {
                return Ok(line.split('#').next().unwrap_or(line).trim().to_string());
            }
        }
    }
    Ok(name.replace(['_', '-'], " "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bag_of_words_ignores_case_and_punctuation_and_sums_to_one() {
        let a = bag_of_words("A person walks forward.");
        let b = bag_of_words("a PERSON walks, forward");
        assert_eq!(a, b);
        assert!((a.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert_ne!(a, bag_of_words("a person runs forward"));
        assert!(bag_of_words("  ...  ").iter().all(|v| *v == 0.0));
    }

    #[test]
    fn fnv1a_matches_the_published_test_vector() {
        // FNV-1a 64 of "a" (Fowler, Noll and Vo's reference test suite)
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }
}
