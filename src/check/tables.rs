//! The reference tables of the checks (`data/check/*.csv`): a small CSV reader (quoted
//! fields, `#` comment lines), glob patterns and the `{side}` placeholder.

use crate::error::Error;

/// The texts of the tables; [`Tables::builtin`] holds the project's own.
#[derive(Clone, Debug)]
pub struct Tables {
    /// `parameter,min,max,unit,source`.
    pub parameter_ranges: String,
    /// `coordinate,direction,sign,source`.
    pub coordinate_directions: String,
    /// `muscles,coordinate,direction,source`.
    pub agonist_signs: String,
    /// `coordinate,direction,min_nm,max_nm,source`.
    pub max_isometric_moments: String,
    /// `coordinate,direction,max_deg,source`.
    pub range_of_motion: String,
    /// `muscles,coordinates,max_m,source`.
    pub moment_arm_bounds: String,
    /// `body,axis,reference,direction,min_angle_deg,source`.
    pub segment_directions: String,
}

impl Tables {
    pub fn builtin() -> Tables {
        Tables {
            parameter_ranges: include_str!("../../data/check/muscle_parameter_ranges.csv").into(),
            coordinate_directions: include_str!("../../data/check/coordinate_directions.csv")
                .into(),
            agonist_signs: include_str!("../../data/check/agonist_signs.csv").into(),
            max_isometric_moments: include_str!("../../data/check/max_isometric_moments.csv")
                .into(),
            range_of_motion: include_str!("../../data/check/range_of_motion.csv").into(),
            moment_arm_bounds: include_str!("../../data/check/moment_arm_bounds.csv").into(),
            segment_directions: include_str!("../../data/check/segment_directions.csv").into(),
        }
    }

    /// Parses the tables; an error names the table and line.
    pub fn parse(&self) -> crate::Result<ParsedTables> {
        let ranges = parse_ranges(&self.parameter_ranges)?;
        let directions = parse_directions(&self.coordinate_directions)?;
        Ok(ParsedTables {
            ranges,
            agonists: parse_agonists(&self.agonist_signs, &directions)?,
            moments: parse_moments(&self.max_isometric_moments, &directions)?,
            range_of_motion: parse_range_of_motion(&self.range_of_motion, &directions)?,
            moment_arm_bounds: parse_moment_arm_bounds(&self.moment_arm_bounds)?,
            segment_directions: parse_segment_directions(&self.segment_directions)?,
            directions,
        })
    }
}

/// `muscle_parameter_ranges.csv`: min ≤ max, parameters among [`PARAMETERS`].
fn parse_ranges(text: &str) -> crate::Result<Vec<ParameterRange>> {
    let t = "muscle_parameter_ranges.csv";
    rows(t, text, &["parameter", "min", "max", "unit", "source"])?
        .into_iter()
        .map(|(line, f)| {
            let (min, max) = (number(t, line, &f[1])?, number(t, line, &f[2])?);
            if !(min <= max) {
                return Err(table_err(t, line, format!("min {min} exceeds max {max}")));
            }
            if !PARAMETERS.contains(&f[0].as_str()) {
                return Err(table_err(
                    t,
                    line,
                    format!("unknown parameter `{}` (one of {PARAMETERS:?})", f[0]),
                ));
            }
            Ok(ParameterRange {
                parameter: f[0].clone(),
                min,
                max,
                unit: f[3].clone(),
                source: f[4].clone(),
            })
        })
        .collect()
}

/// `coordinate_directions.csv`: signs `+`, `-`, `wider` or `narrower`.
fn parse_directions(text: &str) -> crate::Result<Vec<DirectionRow>> {
    let t = "coordinate_directions.csv";
    rows(t, text, &["coordinate", "direction", "sign", "source"])?
        .into_iter()
        .map(|(line, f)| {
            let sign = match f[2].as_str() {
                "+" => DirectionSign::Positive,
                "-" => DirectionSign::Negative,
                "wider" => DirectionSign::WiderSide,
                "narrower" => DirectionSign::NarrowerSide,
                other => {
                    return Err(table_err(
                        t,
                        line,
                        format!("sign must be +, -, wider or narrower, found `{other}`"),
                    ));
                }
            };
            Ok(DirectionRow {
                coordinate: f[0].clone(),
                direction: f[1].clone(),
                sign,
                source: f[3].clone(),
            })
        })
        .collect()
}

/// An error unless `coordinate` `direction` is a row of `directions`; `t` and `line` name
/// the row that refers to it.
fn known_direction(
    directions: &[DirectionRow],
    t: &str,
    line: usize,
    coordinate: &str,
    direction: &str,
) -> crate::Result<()> {
    if directions
        .iter()
        .any(|d| d.coordinate == coordinate && d.direction == direction)
    {
        Ok(())
    } else {
        Err(table_err(
            t,
            line,
            format!("`{coordinate}` `{direction}` is not in coordinate_directions.csv"),
        ))
    }
}

/// `agonist_signs.csv`: `|`-separated muscle patterns, a known coordinate direction.
fn parse_agonists(text: &str, directions: &[DirectionRow]) -> crate::Result<Vec<AgonistRow>> {
    let t = "agonist_signs.csv";
    rows(t, text, &["muscles", "coordinate", "direction", "source"])?
        .into_iter()
        .map(|(line, f)| {
            known_direction(directions, t, line, &f[1], &f[2])?;
            Ok(AgonistRow {
                muscles: f[0].split('|').map(|p| p.trim().to_string()).collect(),
                coordinate: f[1].clone(),
                direction: f[2].clone(),
                source: f[3].clone(),
            })
        })
        .collect()
}

/// `max_isometric_moments.csv`: a known coordinate direction, 0 ≤ min_nm ≤ max_nm.
fn parse_moments(text: &str, directions: &[DirectionRow]) -> crate::Result<Vec<MomentRow>> {
    let t = "max_isometric_moments.csv";
    rows(
        t,
        text,
        &["coordinate", "direction", "min_nm", "max_nm", "source"],
    )?
    .into_iter()
    .map(|(line, f)| {
        known_direction(directions, t, line, &f[0], &f[1])?;
        let (min_nm, max_nm) = (number(t, line, &f[2])?, number(t, line, &f[3])?);
        if !(0.0 <= min_nm && min_nm <= max_nm) {
            return Err(table_err(
                t,
                line,
                format!("need 0 <= min_nm <= max_nm, found {min_nm}, {max_nm}"),
            ));
        }
        Ok(MomentRow {
            coordinate: f[0].clone(),
            direction: f[1].clone(),
            min_nm,
            max_nm,
            source: f[4].clone(),
        })
    })
    .collect()
}

/// `range_of_motion.csv`: a known coordinate direction, max_deg in [0, 360].
fn parse_range_of_motion(text: &str, directions: &[DirectionRow]) -> crate::Result<Vec<RomRow>> {
    let t = "range_of_motion.csv";
    rows(t, text, &["coordinate", "direction", "max_deg", "source"])?
        .into_iter()
        .map(|(line, f)| {
            known_direction(directions, t, line, &f[0], &f[1])?;
            let max_deg = number(t, line, &f[2])?;
            if !(0.0..=360.0).contains(&max_deg) {
                return Err(table_err(
                    t,
                    line,
                    format!("max_deg must be in [0, 360], found {max_deg}"),
                ));
            }
            Ok(RomRow {
                coordinate: f[0].clone(),
                direction: f[1].clone(),
                max_deg,
                source: f[3].clone(),
            })
        })
        .collect()
}

/// `segment_directions.csv`: two non-zero 3-vectors (normalised here), min_angle_deg in
/// [0, 180].
fn parse_segment_directions(text: &str) -> crate::Result<Vec<SegmentDirectionRow>> {
    let t = "segment_directions.csv";
    let vector = |line: usize, field: &str, name: &str| -> crate::Result<[f64; 3]> {
        let v: Vec<f64> = field
            .split_whitespace()
            .map(|x| number(t, line, x))
            .collect::<crate::Result<_>>()?;
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if v.len() != 3 || !(norm > 0.0 && norm.is_finite()) {
            return Err(table_err(
                t,
                line,
                format!("{name} must be three numbers, not all zero; found '{field}'"),
            ));
        }
        Ok([v[0] / norm, v[1] / norm, v[2] / norm])
    };
    rows(
        t,
        text,
        &[
            "body",
            "axis",
            "reference",
            "direction",
            "min_angle_deg",
            "source",
        ],
    )?
    .into_iter()
    .map(|(line, f)| {
        let min_angle_deg = number(t, line, &f[4])?;
        if !(0.0..=180.0).contains(&min_angle_deg) {
            return Err(table_err(
                t,
                line,
                format!("min_angle_deg must be in [0, 180], found {min_angle_deg}"),
            ));
        }
        Ok(SegmentDirectionRow {
            body: f[0].clone(),
            axis: vector(line, &f[1], "axis")?,
            reference: f[2].clone(),
            direction: vector(line, &f[3], "direction")?,
            min_angle_deg,
            source: f[5].clone(),
        })
    })
    .collect()
}

/// `moment_arm_bounds.csv`: `|`-separated non-empty muscle and coordinate patterns, a
/// positive max_m.
fn parse_moment_arm_bounds(text: &str) -> crate::Result<Vec<MomentArmBoundRow>> {
    let t = "moment_arm_bounds.csv";
    rows(t, text, &["muscles", "coordinates", "max_m", "source"])?
        .into_iter()
        .map(|(line, f)| {
            let max_m = number(t, line, &f[2])?;
            if !(max_m > 0.0) {
                return Err(table_err(
                    t,
                    line,
                    format!("max_m must be positive, found {max_m}"),
                ));
            }
            let patterns = |text: &str| -> Vec<String> {
                text.split('|').map(|p| p.trim().to_string()).collect()
            };
            let (muscles, coordinates) = (patterns(&f[0]), patterns(&f[1]));
            if muscles.iter().chain(&coordinates).any(|p| p.is_empty()) {
                return Err(table_err(t, line, "empty pattern".into()));
            }
            Ok(MomentArmBoundRow {
                muscles,
                coordinates,
                max_m,
                source: f[3].clone(),
            })
        })
        .collect()
}

/// The muscle parameters the range table may name.
pub const PARAMETERS: [&str; 5] = [
    "max_isometric_force",
    "optimal_fiber_length",
    "tendon_slack_length",
    "pennation_angle_at_optimal",
    "max_contraction_velocity",
];

#[derive(Clone, Debug, PartialEq)]
pub struct ParameterRange {
    pub parameter: String,
    pub min: f64,
    pub max: f64,
    pub unit: String,
    pub source: String,
}

/// Which sign of a coordinate is an anatomical direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectionSign {
    Positive,
    Negative,
    /// The side of the range whose extreme is larger in magnitude (the knee's flexion).
    WiderSide,
    NarrowerSide,
}

impl DirectionSign {
    /// +1 or −1 for a coordinate with this range.
    pub fn resolve(&self, range: [f64; 2]) -> f64 {
        let wider = if range[1].abs() >= range[0].abs() {
            1.0
        } else {
            -1.0
        };
        match self {
            DirectionSign::Positive => 1.0,
            DirectionSign::Negative => -1.0,
            DirectionSign::WiderSide => wider,
            DirectionSign::NarrowerSide => -wider,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct DirectionRow {
    /// Coordinate name, possibly with `{side}`.
    pub coordinate: String,
    pub direction: String,
    pub sign: DirectionSign,
    pub source: String,
}

#[derive(Clone, Debug, PartialEq)]
pub struct AgonistRow {
    /// Glob patterns, possibly with `{side}`.
    pub muscles: Vec<String>,
    pub coordinate: String,
    pub direction: String,
    pub source: String,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MomentRow {
    pub coordinate: String,
    pub direction: String,
    pub min_nm: f64,
    pub max_nm: f64,
    pub source: String,
}

#[derive(Clone, Debug, PartialEq)]
pub struct RomRow {
    pub coordinate: String,
    pub direction: String,
    /// Largest excursion from neutral in this direction (degrees).
    pub max_deg: f64,
    pub source: String,
}

/// A segment's axis kept at least `min_angle_deg` from a direction of another body.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentDirectionRow {
    /// Body name, possibly with `{side}`.
    pub body: String,
    /// Unit axis in `body`'s frame.
    pub axis: [f64; 3],
    /// Body name, possibly with `{side}`.
    pub reference: String,
    /// Unit direction in `reference`'s frame.
    pub direction: [f64; 3],
    pub min_angle_deg: f64,
    pub source: String,
}

/// The largest plausible |r| of the muscles matching `muscles` about the coordinates matching
/// `coordinates` (glob patterns, possibly with `{side}`).
#[derive(Clone, Debug, PartialEq)]
pub struct MomentArmBoundRow {
    pub muscles: Vec<String>,
    pub coordinates: Vec<String>,
    /// m.
    pub max_m: f64,
    pub source: String,
}

impl MomentArmBoundRow {
    /// The bound on muscle `muscle` about coordinate `coordinate`, when this row covers the
    /// pair: `{side}` stands for the same side in both patterns.
    pub fn bound(&self, muscle: &str, coordinate: &str) -> Option<f64> {
        let covers = |side: Option<&str>| {
            let fill = |p: &String| match side {
                Some(s) => p.replace("{side}", s),
                None => p.clone(),
            };
            self.muscles.iter().any(|p| glob_match(&fill(p), muscle))
                && self
                    .coordinates
                    .iter()
                    .any(|p| glob_match(&fill(p), coordinate))
        };
        let sided = self
            .muscles
            .iter()
            .chain(&self.coordinates)
            .any(|p| p.contains("{side}"));
        let hit = if sided {
            ["r", "l"].into_iter().any(|s| covers(Some(s)))
        } else {
            covers(None)
        };
        hit.then_some(self.max_m)
    }
}

/// The parsed tables.
#[derive(Clone, Debug, PartialEq)]
pub struct ParsedTables {
    pub ranges: Vec<ParameterRange>,
    pub directions: Vec<DirectionRow>,
    pub agonists: Vec<AgonistRow>,
    pub moments: Vec<MomentRow>,
    pub range_of_motion: Vec<RomRow>,
    pub moment_arm_bounds: Vec<MomentArmBoundRow>,
    pub segment_directions: Vec<SegmentDirectionRow>,
}

impl ParsedTables {
    /// The smallest bound of the rows covering muscle `muscle` about coordinate
    /// `coordinate`, with the row's index; `None` when no row does.
    pub fn moment_arm_bound(&self, muscle: &str, coordinate: &str) -> Option<(f64, usize)> {
        self.moment_arm_bounds
            .iter()
            .enumerate()
            .filter_map(|(i, row)| row.bound(muscle, coordinate).map(|b| (b, i)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// The sign (+1/−1) of `direction` of the model coordinate `name` (with range `range`),
    /// looked up through the table's `{side}` patterns.
    pub fn direction_sign(
        &self,
        table_coordinate: &str,
        direction: &str,
        range: [f64; 2],
    ) -> Option<f64> {
        self.directions
            .iter()
            .find(|d| d.coordinate == table_coordinate && d.direction == direction)
            .map(|d| d.sign.resolve(range))
    }

    /// The physiological range of motion of the model coordinate `name` (range `range`):
    /// each side bounded by the table's excursion in the direction of that sign, when the
    /// table has it; the result is intersected with `range`.
    pub fn range_of_motion(&self, name: &str, range: [f64; 2]) -> [f64; 2] {
        let mut rom = range;
        for row in &self.range_of_motion {
            if !sides(&row.coordinate).iter().any(|(c, _)| c == name) {
                continue;
            }
            let Some(sign) = self.direction_sign(&row.coordinate, &row.direction, range) else {
                continue;
            };
            let bound = sign * row.max_deg.to_radians();
            if sign > 0.0 {
                rom[1] = rom[1].min(bound);
            } else {
                rom[0] = rom[0].max(bound);
            }
        }
        rom
    }
}

/// `pattern` with `{side}` replaced by each side it is used with: `[(pattern, None)]` without
/// a placeholder, else `[(…_r, Some("r")), (…_l, Some("l"))]`.
pub(crate) fn sides(pattern: &str) -> Vec<(String, Option<&'static str>)> {
    if pattern.contains("{side}") {
        ["r", "l"]
            .into_iter()
            .map(|s| (pattern.replace("{side}", s), Some(s)))
            .collect()
    } else {
        vec![(pattern.to_string(), None)]
    }
}

/// Glob matching with `*` for any text (case-sensitive).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    if parts.len() == 1 {
        return pattern == name;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !name.starts_with(first) || name.len() < first.len() + last.len() || !name.ends_with(last) {
        return false;
    }
    let mut rest = &name[first.len()..name.len() - last.len()];
    for part in &parts[1..parts.len() - 1] {
        match rest.find(part) {
            Some(i) => rest = &rest[i + part.len()..],
            None => return false,
        }
    }
    true
}

fn table_err(table: &str, line: usize, message: String) -> Error {
    Error::Table {
        table: table.to_string(),
        line,
        message,
    }
}

fn number(table: &str, line: usize, text: &str) -> crate::Result<f64> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| table_err(table, line, format!("`{text}` is not a finite number")))
}

/// Data rows (1-based line, fields) after checking the header.
fn rows(table: &str, text: &str, header: &[&str]) -> crate::Result<Vec<(usize, Vec<String>)>> {
    let mut out = Vec::new();
    let mut seen_header = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        if raw.trim().is_empty() || raw.trim_start().starts_with('#') {
            continue;
        }
        let fields = split_csv(raw).map_err(|m| table_err(table, line, m))?;
        if !seen_header {
            if fields != header {
                return Err(table_err(
                    table,
                    line,
                    format!("header must be `{}`", header.join(",")),
                ));
            }
            seen_header = true;
            continue;
        }
        if fields.len() != header.len() {
            return Err(table_err(
                table,
                line,
                format!("expected {} fields, found {}", header.len(), fields.len()),
            ));
        }
        if fields.last().is_some_and(|s| s.trim().is_empty()) {
            return Err(table_err(table, line, "empty source".into()));
        }
        out.push((line, fields));
    }
    if !seen_header {
        return Err(table_err(table, 1, "no header".into()));
    }
    Ok(out)
}

/// One CSV line: fields separated by commas, optionally double-quoted ("" inside quotes).
fn split_csv(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut chars = line.chars().peekable();
    loop {
        let mut field = String::new();
        if chars.peek() == Some(&'"') {
            chars.next();
            loop {
                match chars.next() {
                    None => return Err("unterminated quoted field".into()),
                    Some('"') if chars.peek() == Some(&'"') => {
                        chars.next();
                        field.push('"');
                    }
                    Some('"') => break,
                    Some(c) => field.push(c),
                }
            }
            match chars.next() {
                None => {
                    fields.push(field);
                    return Ok(fields);
                }
                Some(',') => fields.push(field),
                Some(c) => return Err(format!("unexpected `{c}` after a quoted field")),
            }
        } else {
            loop {
                match chars.next() {
                    None => {
                        fields.push(field.trim().to_string());
                        return Ok(fields);
                    }
                    Some(',') => break,
                    Some(c) => field.push(c),
                }
            }
            fields.push(field.trim().to_string());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_tables_parse_and_cite_a_source_on_every_row() {
        let t = Tables::builtin().parse().unwrap();
        assert_eq!(t.ranges.len(), PARAMETERS.len());
        assert!(t.agonists.len() >= 15 && t.moments.len() >= 15);
        assert!(t.ranges.iter().all(|r| !r.source.is_empty()));
        assert!(!t.segment_directions.is_empty());
        assert!(t.segment_directions.iter().all(|r| !r.source.is_empty()));
    }

    #[test]
    fn segment_directions_need_two_vectors_and_an_angle() {
        let header = "body,axis,reference,direction,min_angle_deg,source\n";
        let ok = parse_segment_directions(&format!("{header}a,0 -2 0,b,-1 0 0,30,s\n")).unwrap();
        assert_eq!(ok[0].axis, [0.0, -1.0, 0.0]);
        for bad in [
            "a,0 0 0,b,1 0 0,30,s",
            "a,0 1,b,1 0 0,30,s",
            "a,0 1 0,b,1 0 0,190,s",
        ] {
            let e = parse_segment_directions(&format!("{header}{bad}\n")).unwrap_err();
            assert!(e.to_string().contains("segment_directions.csv:2"), "{e}");
        }
    }

    #[test]
    fn moment_arm_bounds_pair_muscle_and_coordinate_sides() {
        let t = Tables::builtin().parse().unwrap();
        assert!(t.moment_arm_bounds.len() >= 7);
        assert_eq!(
            t.moment_arm_bound("DELT3_l", "arm_flex_l").map(|b| b.0),
            Some(0.07)
        );
        assert_eq!(
            t.moment_arm_bound("soleus_r", "ankle_angle_r").map(|b| b.0),
            Some(0.08)
        );
        assert_eq!(
            t.moment_arm_bound("x", "lumbar_bending").map(|b| b.0),
            Some(0.16)
        );
        assert!(t.moment_arm_bound("x", "pelvis_tx").is_none());
        // a {side} row pairs sides: a right muscle about a left coordinate is not covered
        let row = MomentArmBoundRow {
            muscles: vec!["delt_{side}".into()],
            coordinates: vec!["arm_{side}".into()],
            max_m: 0.05,
            source: "test".into(),
        };
        assert_eq!(row.bound("delt_r", "arm_r"), Some(0.05));
        assert_eq!(row.bound("delt_r", "arm_l"), None);
    }

    #[test]
    fn glob_matches_stars_anywhere() {
        assert!(glob_match("vas*_r", "vas_med_r"));
        assert!(glob_match("vas*_r", "vasmed_r"));
        assert!(!glob_match("vas*_r", "vasmed_l"));
        assert!(glob_match("BIClong", "BIClong"));
        assert!(!glob_match("bic*_r", "bi_r"));
        assert!(glob_match("*", "x"));
    }

    #[test]
    fn csv_fields_may_be_quoted() {
        assert_eq!(
            split_csv(r#"a,"b, c",1"#).unwrap(),
            vec!["a".to_string(), "b, c".into(), "1".into()]
        );
        assert!(split_csv(r#"a,"b"#).is_err());
    }

    #[test]
    fn knee_flexion_is_the_wide_side_of_the_range() {
        assert_eq!(DirectionSign::WiderSide.resolve([-2.09, 0.17]), -1.0);
        assert_eq!(DirectionSign::WiderSide.resolve([0.0, 2.09]), 1.0);
    }
}
