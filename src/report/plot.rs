//! The plots of the report pages, drawn as SVG text with `plotters`: line charts over time,
//! heat maps (rows × frames) and histograms. Every plot is `WIDTH` × its height in pixels, on a
//! white background, its data drawn in the colours of [`PALETTE`].

use plotters::prelude::*;

/// Width of every plot (px).
pub const WIDTH: u32 = 900;

/// Series colours (Tableau's ten): saturated, so that drawn data tells itself apart from the
/// black and grey of axes and text.
pub const PALETTE: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
];

fn color(i: usize) -> RGBColor {
    let (r, g, b) = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

fn failed(e: impl std::fmt::Display) -> crate::Error {
    crate::Error::invalid("plot", e.to_string())
}

/// One line of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    /// One value per time sample; NaN leaves a gap.
    pub values: Vec<f64>,
    /// Dashed (a reference beside an estimate).
    pub dashed: bool,
    /// Index into [`PALETTE`].
    pub color: usize,
}

/// The range of `values` (finite ones), widened by 5 % and never empty.
fn range_of<'a>(values: impl Iterator<Item = &'a f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9 * (1.0 + hi.abs().max(lo.abs())));
    (lo - pad, hi + pad)
}

/// A line chart of `series` over `time` (s).
pub fn line_chart(
    title: &str,
    y_label: &str,
    time: &[f64],
    series: &[Series],
    height: u32,
) -> crate::Result<String> {
    line_chart_over(title, "time (s)", y_label, time, series, height)
}

/// A line chart of `series` over the abscissae `time`, labelled `x_label`.
pub fn line_chart_over(
    title: &str,
    x_label: &str,
    y_label: &str,
    time: &[f64],
    series: &[Series],
    height: u32,
) -> crate::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        root.fill(&WHITE).map_err(failed)?;
        let (t0, t1) = range_of(time.iter());
        let (y0, y1) = range_of(series.iter().flat_map(|s| s.values.iter()));
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(32)
            .y_label_area_size(64)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(failed)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(failed)?;
        for s in series {
            let c = color(s.color);
            let style = c.stroke_width(2);
            // runs of finite values, so that NaN leaves a gap
            let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
            for (t, v) in time.iter().zip(&s.values) {
                if v.is_finite() {
                    if let Some(r) = runs.last_mut() {
                        r.push((*t, *v));
                    }
                } else if runs.last().is_some_and(|r| !r.is_empty()) {
                    runs.push(Vec::new());
                }
            }
            let mut first = true;
            for run in runs.into_iter().filter(|r| !r.is_empty()) {
                let drawn = if s.dashed {
                    chart
                        .draw_series(DashedLineSeries::new(run, 6, 4, style))
                        .map_err(failed)?
                } else {
                    chart
                        .draw_series(LineSeries::new(run, style))
                        .map_err(failed)?
                };
                if first {
                    drawn.label(s.name.clone()).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
                    first = false;
                }
            }
        }
        if !series.is_empty() {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .position(SeriesLabelPosition::UpperRight)
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(failed)?;
        }
        root.present().map_err(failed)?;
    }
    Ok(svg)
}

/// The colour of a heat-map value w ∈ [0, 1]: white to the palette's first colour darkened.
fn shade(w: f64) -> (u8, u8, u8) {
    let (r, g, b) = PALETTE[0];
    let mix = |c: u8| (255.0 - w.clamp(0.0, 1.0) * (255.0 - c as f64 * 0.6)).round() as u8;
    (mix(r), mix(g), mix(b))
}

/// An uncompressed 8-bit BMP of `rows` × `columns` palette indices (row 0 at the top) with a
/// 256-entry palette: what browsers show from a `data:image/bmp` URI.
pub fn bmp(indices: &[u8], rows: usize, columns: usize, palette: &[(u8, u8, u8); 256]) -> Vec<u8> {
    let stride = columns.div_ceil(4) * 4;
    let offset = 14 + 40 + 256 * 4;
    let size = offset + stride * rows;
    let mut out = Vec::with_capacity(size);
    let u32le = |o: &mut Vec<u8>, v: usize| o.extend_from_slice(&(v as u32).to_le_bytes());
    out.extend_from_slice(b"BM");
    u32le(&mut out, size);
    u32le(&mut out, 0);
    u32le(&mut out, offset);
    // BITMAPINFOHEADER: width, height (positive: rows bottom-up), 1 plane, 8 bits, no
    // compression, image size, 2835 px/m, 256 colours
    u32le(&mut out, 40);
    u32le(&mut out, columns);
    u32le(&mut out, rows);
    out.extend_from_slice(&1u16.to_le_bytes());
    out.extend_from_slice(&8u16.to_le_bytes());
    u32le(&mut out, 0);
    u32le(&mut out, stride * rows);
    u32le(&mut out, 2835);
    u32le(&mut out, 2835);
    u32le(&mut out, 256);
    u32le(&mut out, 0);
    for &(r, g, b) in palette {
        out.extend_from_slice(&[b, g, r, 0]);
    }
    for row in (0..rows).rev() {
        out.extend_from_slice(&indices[row * columns..(row + 1) * columns]);
        out.resize(out.len() + stride - columns, 0);
    }
    out
}

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const TABLE: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(TABLE[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A heat map over time: `values` rows × columns (row-major, the columns spanning `time` =
/// (first, last) in s) in [0, `max`], drawn light (0) to dark (`max`) as an image inside the
/// chart's axes, with `labels` (row index, text) naming groups of rows.
#[allow(clippy::too_many_arguments)]
pub fn heat_map(
    title: &str,
    time: (f64, f64),
    values: &[f64],
    rows: usize,
    columns: usize,
    max: f64,
    labels: &[(usize, String)],
    height: u32,
) -> crate::Result<String> {
    let mut svg = String::new();
    let (xs, ys);
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        root.fill(&WHITE).map_err(failed)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(32)
            .y_label_area_size(130)
            .build_cartesian_2d(time.0..time.1.max(time.0 + 1e-9), rows.max(1) as f64..0f64)
            .map_err(failed)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("time (s)")
            .y_labels(0)
            .draw()
            .map_err(failed)?;
        (xs, ys) = chart.plotting_area().get_pixel_range();
        for (row, text) in labels {
            let y = *row as f64;
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(time.0, y), (time.1, y)],
                    BLACK.mix(0.25),
                )))
                .map_err(failed)?;
            // the group's name left of the axis
            root.draw(&Text::new(
                text.clone(),
                (8, chart.backend_coord(&(time.0, y)).1),
                ("sans-serif", 10).into_font().color(&BLACK),
            ))
            .map_err(failed)?;
        }
        root.present().map_err(failed)?;
    }
    let mut palette = [(0u8, 0u8, 0u8); 256];
    for (i, p) in palette.iter_mut().enumerate() {
        *p = shade(i as f64 / 255.0);
    }
    let indices: Vec<u8> = values
        .iter()
        .map(|v| ((v / max).clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let image = format!(
        "<image x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" preserveAspectRatio=\"none\" \
         style=\"image-rendering:pixelated\" href=\"data:image/bmp;base64,{}\"/>\n",
        xs.start,
        ys.start,
        xs.end - xs.start,
        ys.end - ys.start,
        base64(&bmp(&indices, rows, columns, &palette))
    );
    // under the separators and labels: right after the background
    let at = svg.find("/>").map_or(0, |i| i + 2);
    svg.insert_str(at, &format!("\n{image}"));
    Ok(svg)
}

/// A histogram of `values` in `bins` equal bins over their range.
pub fn histogram(title: &str, x_label: &str, values: &[f64], bins: usize) -> crate::Result<String> {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let (lo, hi) = range_of(finite.iter());
    let width = (hi - lo) / bins.max(1) as f64;
    let mut counts = vec![0usize; bins.max(1)];
    for v in &finite {
        let i = (((v - lo) / width) as usize).min(counts.len() - 1);
        counts[i] += 1;
    }
    let top = counts.iter().copied().max().unwrap_or(0).max(1);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH / 2 - 10, 220)).into_drawing_area();
        root.fill(&WHITE).map_err(failed)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(40)
            .build_cartesian_2d(lo..hi, 0usize..top + top / 10 + 1)
            .map_err(failed)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(x_label)
            .y_desc("clips")
            .draw()
            .map_err(failed)?;
        chart
            .draw_series(
                counts
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| **c > 0)
                    .map(|(i, c)| {
                        let x0 = lo + width * i as f64;
                        Rectangle::new([(x0, 0), (x0 + width, *c)], color(0).filled())
                    }),
            )
            .map_err(failed)?;
        root.present().map_err(failed)?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (text, code) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(text.as_bytes()), code);
        }
    }

    #[test]
    fn bmp_rows_are_padded_and_bottom_up() {
        let palette = [(1u8, 2u8, 3u8); 256];
        let b = bmp(&[10, 11, 12, 20, 21, 22], 2, 3, &palette);
        let offset = 14 + 40 + 1024;
        assert_eq!(&b[..2], b"BM");
        assert_eq!(
            u32::from_le_bytes(b[2..6].try_into().unwrap()) as usize,
            b.len()
        );
        assert_eq!(b.len(), offset + 2 * 4);
        // the bottom row first, each padded to 4 bytes
        assert_eq!(&b[offset..], &[20, 21, 22, 0, 10, 11, 12, 0]);
        assert_eq!(&b[54..58], &[3, 2, 1, 0]);
    }
}
