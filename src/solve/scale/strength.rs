//! Muscle strength scaling: every muscle's maximum isometric force multiplied by one factor k,
//!
//!   F_max ← k · F_max,
//!
//! written into the model file's text (nothing else changes), as OpenSim users strengthen a
//! model for tasks that ask more of it than the cadaver- or walking-derived forces give (the
//! scripting examples' "strengthen model": the same loop over the muscles). It is not part of
//! OpenSim's Scale tool: a subject's strength is not measured by markers. A muscle is an
//! element of the force set whose class name ends in `Muscle` (or holds `Muscle_`, the
//! deprecated classes), as the `.osim` reader takes it; each must state its
//! `<max_isometric_force>`.

use super::frames::{child, text_node};
use super::markers::splice;
use crate::error::Error;

/// The range of a strength factor. Strengthened models for tasks beyond walking take 1.5–3;
/// 10⁻³⁰⁰ or 10³⁰⁰ are typing errors, and the second put infinite forces in float32 outputs.
pub const MIN_STRENGTH_FACTOR: f64 = 0.01;
pub const MAX_STRENGTH_FACTOR: f64 = 100.0;

/// `xml` (read as `source`) with every muscle's `<max_isometric_force>` × `factor` (written in
/// the shortest form that reads back to the same `f64`; `factor` within
/// [`MIN_STRENGTH_FACTOR`]..=[`MAX_STRENGTH_FACTOR`]). Returns the text and the number of
/// muscles changed.
pub fn scale_muscle_strength(
    xml: &str,
    source: &str,
    factor: f64,
) -> crate::Result<(String, usize)> {
    if !(MIN_STRENGTH_FACTOR..=MAX_STRENGTH_FACTOR).contains(&factor) {
        return Err(Error::invalid(
            "factor",
            format!(
                "{factor}: a muscle strength factor must be from {MIN_STRENGTH_FACTOR} to \
                 {MAX_STRENGTH_FACTOR}"
            ),
        ));
    }
    let doc = super::parse_document(xml, source)?;
    let mut parts = Vec::new();
    for n in doc.descendants().filter(|n| {
        let tag = n.tag_name().name();
        n.is_element()
            && (tag.ends_with("Muscle") || tag.contains("Muscle_"))
            && n.parent_element()
                .is_some_and(|p| p.has_tag_name("objects"))
    }) {
        let element = || {
            format!(
                "{} \"{}\"",
                n.tag_name().name(),
                n.attribute("name").unwrap_or("")
            )
        };
        let line = doc.text_pos_at(n.range().start).row;
        let target = child(n, "max_isometric_force")
            .and_then(text_node)
            .ok_or_else(|| Error::Model {
                file: source.to_string(),
                line,
                element: element(),
                message: "no <max_isometric_force> to scale".into(),
            })?;
        let text = target.text().unwrap_or("").trim();
        let value: f64 = text.parse().map_err(|_| Error::Model {
            file: source.to_string(),
            line,
            element: element(),
            message: format!("<max_isometric_force> \"{text}\" is not a number"),
        })?;
        parts.push((target.range(), format!("{}", value * factor)));
    }
    let count = parts.len();
    Ok((splice(xml, parts), count))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Model;
    use crate::muscle::MuscleSet;

    #[test]
    fn every_muscle_and_nothing_else_is_strengthened() {
        let xml = crate::DEFAULT_MODEL_OSIM;
        let (text, count) = scale_muscle_strength(xml, "default", 1.7).unwrap();
        let (a, b) = (
            Model::from_osim_str(xml, "default").unwrap(),
            Model::from_osim_str(&text, "strong").unwrap(),
        );
        let (ma, mb) = (MuscleSet::new(&a).unwrap(), MuscleSet::new(&b).unwrap());
        assert_eq!(count, 324);
        assert_eq!(ma.muscles.len(), mb.muscles.len());
        for (x, y) in ma.muscles.iter().zip(&mb.muscles) {
            let (p, r) = (x.params(), y.params());
            assert_eq!(r.max_isometric_force, p.max_isometric_force * 1.7);
            let mut same = *r;
            same.max_isometric_force = p.max_isometric_force;
            assert_eq!(&same, p);
        }
        // one line per muscle changed, and only those
        let changed = xml
            .lines()
            .zip(text.lines())
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(changed, 324);
        assert_eq!(xml.lines().count(), text.lines().count());
    }

    #[test]
    fn bad_factors_and_files_are_errors() {
        for k in [
            0.0,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            1e-300,
            0.009,
            100.5,
            1e300,
        ] {
            let e = scale_muscle_strength(crate::DEFAULT_MODEL_OSIM, "default", k).unwrap_err();
            assert!(e.to_string().contains("factor"), "{e}");
        }
        let xml = crate::DEFAULT_MODEL_OSIM.replacen(
            "<max_isometric_force>",
            "<max_isometric_force>x",
            1,
        );
        let e = scale_muscle_strength(&xml, "bad.osim", 2.0).unwrap_err();
        assert!(e.to_string().contains("is not a number"), "{e}");
        assert!(e.to_string().contains("bad.osim"), "{e}");
    }
}
