//! Low-pass filtering of sampled signals, as OpenSim's tools do it: odd-reflection padding at
//! both ends, then a third-order Butterworth filter run forward and backward (zero lag).

use crate::text::short_number;

/// Pads a signal with `pad` points at each end by odd reflection about its end values,
/// x(−i) = 2 x(0) − x(i), which keeps value and slope continuous (OpenSim's Signal::Pad; the
/// time column is padded the same way, extending the sampling grid).
pub fn pad_odd(signal: &[f64], pad: usize) -> Vec<f64> {
    let n = signal.len();
    if pad == 0 || n < 2 {
        return signal.to_vec();
    }
    let pad = pad.min(n - 1);
    let mut out = Vec::with_capacity(n + 2 * pad);
    for i in (1..=pad).rev() {
        out.push(2.0 * signal[0] - signal[i]);
    }
    out.extend_from_slice(signal);
    for i in 1..=pad {
        out.push(2.0 * signal[n - 1] - signal[n - 1 - i]);
    }
    out
}

/// The most samples [`accumulated_grid`] makes: ten million rows (about 80 MB a column) is
/// far beyond any recorded motion, and refusing more turns an absurd time column into an
/// error instead of an allocation failure.
pub const MAX_SAMPLES: usize = 10_000_000;

/// The times first, first + dt, first + 2dt, … accumulated by repeated addition while ≤
/// `last`, as OpenSim's `GCVSplineSet::constructStorage` loop makes them (so they carry the
/// same drift). Errors (as a message) when `dt` is not a positive finite number, when
/// `first` or `last` is not finite, when the grid would hold more than [`MAX_SAMPLES`]
/// times, or when the times are so large that adding `dt` no longer changes them.
pub fn accumulated_grid(first: f64, last: f64, dt: f64) -> Result<Vec<f64>, String> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(format!(
            "the sampling interval {dt} s must be a positive finite number"
        ));
    }
    if !(first.is_finite() && last.is_finite()) || last < first {
        return Err(format!(
            "the times [{}, {}] s are not a finite span",
            short_number(first),
            short_number(last)
        ));
    }
    // Rounded up, plus the one sample the drift of repeated addition can add.
    let expected = (last - first) / dt + 2.0;
    if !(expected <= MAX_SAMPLES as f64) {
        return Err(format!(
            "resampling {} s to {} s every {} s would need {expected:.3e} samples, more than \
             the {MAX_SAMPLES} allowed: check the time column",
            short_number(first),
            short_number(last),
            short_number(dt)
        ));
    }
    let cap = expected as usize + 1;
    let mut grid = Vec::with_capacity(cap);
    let mut x = first;
    while x <= last {
        if grid.len() == cap || (!grid.is_empty() && x + dt == x) {
            return Err(format!(
                "the sampling interval {} s is below the resolution of the times near {} s",
                short_number(dt),
                short_number(x)
            ));
        }
        grid.push(x);
        x += dt;
    }
    Ok(grid)
}

/// The highest cutoff [`lowpass_butterworth3`] takes, as a fraction of the sampling rate.
///
/// Towards the Nyquist frequency the filter's poles approach z = −1, so the transient of its
/// start-up (the first three samples copied, as OpenSim starts it) alternates sign from sample
/// to sample and decays slowly: the odd padding of half the samples no longer absorbs it, and
/// a second derivative multiplies an alternating error by 4/dt². OpenSim lowers a cutoff at or
/// above half the rate to 0.49 of it and filters anyway: OpenSim's arm26 IK motion (120 Hz)
/// filtered that way gives peak elbow moments of 1,323 N·m against 2.8 N·m at 6 Hz and
/// 2.7 N·m unfiltered, and the HumanML3D sample (20 fps) at 9.8 Hz leaves 81 % of its joint
/// moments to the reserves against 13 % at 6 Hz. Measured on smooth signals of 20, 40 and
/// 120 samples padded by half their length (the test below), the filtered second
/// differences stay within 10 % of the signal's up to 0.42 of the rate, and reach 1.6–1.8×
/// at 0.44, 2–6× at 0.45, 12–120× at 0.48: 0.4 keeps a margin. Such a cutoff removes little
/// anyway (its gain is above 0.5 up to 0.4 of the rate).
pub const HIGHEST_CUTOFF_FRACTION: f64 = 0.4;

/// The lowest cutoff, in cycles over the recording: f_c ≥ LOWEST_CUTOFF_CYCLES / T for a
/// recording of duration T.
///
/// The zero-lag filter's start-up transient lasts about 1/f_c (its slowest poles decay as
/// e^(−π f_c t)), and the odd padding gives it T/2 at each end to die out in. A cutoff of a
/// fraction of a cycle over the whole recording leaves no room: on a smooth signal (a trend
/// and a slow sine) of 40 to 600 samples padded by half their length (the test below),
/// f_c T = 0.3 gives outputs up to 4–14 times the signal's largest value and 0.01 gives
/// 34–133 times (`--lowpass 0.01` turned joint angles of a radian into 3,100 rad), while at
/// f_c T = 1 the output stays within the signal's range.
pub const LOWEST_CUTOFF_CYCLES: f64 = 1.0;

/// Why `cutoff` Hz cannot filter a recording of `duration` s sampled `dt` apart — above
/// [`HIGHEST_CUTOFF_FRACTION`] of the rate, or below [`LOWEST_CUTOFF_CYCLES`] over the
/// duration — or None.
pub fn cutoff_problem(cutoff: f64, dt: f64, duration: f64) -> Option<String> {
    cutoff_above_rate(cutoff, dt).or_else(|| {
        let lowest = LOWEST_CUTOFF_CYCLES / duration;
        (cutoff < lowest * (1.0 - 1e-9)).then(|| {
            format!(
                "the low-pass cutoff {} Hz is below {LOWEST_CUTOFF_CYCLES} cycle over the \
                 recording's {} s: the filter's start-up transient (about 1/cutoff = {} s) \
                 does not fit in the padding of half the recording at each end, and the \
                 filtered values run away from the data; give a cutoff of at least {} Hz, or \
                 none",
                short_number(cutoff),
                short_number(duration),
                short_number(1.0 / cutoff),
                short_number(millihertz(lowest, f64::ceil))
            )
        })
    })
}

/// Why `cutoff` Hz cannot filter samples `dt` apart (above [`HIGHEST_CUTOFF_FRACTION`] of
/// the rate), or None.
fn cutoff_above_rate(cutoff: f64, dt: f64) -> Option<String> {
    let rate = 1.0 / dt;
    let highest = HIGHEST_CUTOFF_FRACTION * rate;
    // a relative margin, for a rate computed another way (the span over the sample count)
    (cutoff > highest * (1.0 + 1e-9)).then(|| {
        format!(
            "the low-pass cutoff {} Hz is above {HIGHEST_CUTOFF_FRACTION} of the sampling \
             rate ({} Hz): so near the Nyquist frequency the zero-lag Butterworth filter rings \
             (its start-up transient alternates sign from sample to sample) and the \
             derivatives become noise; give a cutoff of at most {} Hz, or none",
            short_number(cutoff),
            short_number(millihertz(rate, f64::round)),
            short_number(millihertz(highest, f64::floor))
        )
    })
}

/// `hz` rounded to 1 mHz by `round` (above 1 Hz; a slower rate is shown as it is).
fn millihertz(hz: f64, round: fn(f64) -> f64) -> f64 {
    if hz >= 1.0 { round(hz * 1e3) / 1e3 } else { hz }
}

/// OpenSim's low-pass of a record sampled `dt` apart: every column padded by odd reflection
/// with half the record at each end ([`pad_odd`]), then filtered by [`lowpass_butterworth3`].
/// Returns the padded times, which the filtered columns then span. An error names the index
/// of the column that could not be filtered.
pub fn lowpass_padded(
    time: &[f64],
    columns: &mut [Vec<f64>],
    dt: f64,
    cutoff: f64,
) -> Result<Vec<f64>, (usize, String)> {
    let pad = time.len() / 2;
    for (k, column) in columns.iter_mut().enumerate() {
        *column = lowpass_butterworth3(&pad_odd(column, pad), dt, cutoff).map_err(|m| (k, m))?;
    }
    Ok(pad_odd(time, pad))
}

/// Third-order low-pass Butterworth filter with cutoff `cutoff` Hz for samples `dt` apart,
/// applied forward then backward (zero phase; the amplitude response is squared, so the
/// effective cutoff is lower, as in OpenSim's Signal::LowpassIIR).
///
/// The discrete filter is the bilinear transform of H(s) = 1/((s+1)(s²+s+1)) with the cutoff
/// prewarped, ω_a = tan(π f_c dt): with D = (ω_a + 1)(ω_a² + ω_a + 1),
///   y_i = (ω_a³/D)(x_i + 3x_{i−1} + 3x_{i−2} + x_{i−3})
///         − b₁ y_{i−1} − b₂ y_{i−2} − b₃ y_{i−3},
///   b₁ = (3ω_a³ + 2ω_a² − 2ω_a − 3)/D, b₂ = (3ω_a³ − 2ω_a² − 2ω_a + 3)/D,
///   b₃ = (ω_a − 1)(ω_a² − ω_a + 1)/D,
/// started (like OpenSim) from the first three samples copied unchanged. Errors (as a
/// message) on fewer than 4 samples, a step or cutoff that is not a positive finite number,
/// and a cutoff above [`HIGHEST_CUTOFF_FRACTION`] of the sampling rate (OpenSim lowers a
/// cutoff at or above half the rate to 0.49 of it, where the filter rings).
pub fn lowpass_butterworth3(signal: &[f64], dt: f64, cutoff: f64) -> Result<Vec<f64>, String> {
    let n = signal.len();
    if n < 4 {
        return Err(format!("at least 4 samples are needed to filter, got {n}"));
    }
    if !(dt > 0.0 && dt.is_finite() && cutoff > 0.0 && cutoff.is_finite()) {
        return Err(format!(
            "sampling interval {dt} s and cutoff {cutoff} Hz must be positive finite numbers"
        ));
    }
    if let Some(problem) = cutoff_above_rate(cutoff, dt) {
        return Err(problem);
    }
    Ok(forward_backward(signal, dt, cutoff))
}

/// The filter of [`lowpass_butterworth3`], its arguments unchecked.
fn forward_backward(signal: &[f64], dt: f64, fc: f64) -> Vec<f64> {
    let n = signal.len();
    let wa = (std::f64::consts::PI * fc * dt).tan();
    let (wa2, wa3) = (wa * wa, wa * wa * wa);
    let d = (wa + 1.0) * (wa2 + wa + 1.0);
    let a = [wa3 / d, 3.0 * wa3 / d, 3.0 * wa3 / d, wa3 / d];
    let b = [
        (3.0 * wa3 + 2.0 * wa2 - 2.0 * wa - 3.0) / d,
        (3.0 * wa3 - 2.0 * wa2 - 2.0 * wa + 3.0) / d,
        (wa - 1.0) * (wa2 - wa + 1.0) / d,
    ];
    let pass = |x: &[f64]| -> Vec<f64> {
        let mut y = x.to_vec();
        for i in 3..n {
            y[i] = a[0] * x[i] + a[1] * x[i - 1] + a[2] * x[i - 2] + a[3] * x[i - 3]
                - b[0] * y[i - 1]
                - b[1] * y[i - 2]
                - b[2] * y[i - 3];
        }
        y
    };
    let mut forward = pass(signal);
    forward.reverse();
    let mut back = pass(&forward);
    back.reverse();
    back
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padding_reflects_oddly_about_the_ends() {
        assert_eq!(
            pad_odd(&[1.0, 2.0, 4.0, 7.0], 2),
            vec![-2.0, 0.0, 1.0, 2.0, 4.0, 7.0, 10.0, 12.0]
        );
    }

    #[test]
    fn a_constant_and_a_ramp_pass_unchanged_and_a_fast_sine_is_removed() {
        let dt = 0.01;
        let n = 400;
        let ramp: Vec<f64> = (0..n).map(|i| 0.3 + 0.5 * i as f64 * dt).collect();
        let padded = pad_odd(&ramp, n / 2);
        let f = lowpass_butterworth3(&padded, dt, 6.0).unwrap();
        for i in n / 2..n / 2 + n {
            assert!((f[i] - padded[i]).abs() < 1e-9, "ramp changed at {i}");
        }
        // DC gain 1: a constant passes exactly (beyond the copied start-up samples).
        let c = lowpass_butterworth3(&[2.5; 50], dt, 6.0).unwrap();
        assert!(c.iter().all(|v| (v - 2.5).abs() < 1e-12));
        // 30 Hz against a 6 Hz cutoff: attenuated by |H|² ≈ (6/30)⁶ ≈ 6.4e-5 twice over.
        let s: Vec<f64> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * 30.0 * i as f64 * dt).sin())
            .collect();
        let f = lowpass_butterworth3(&pad_odd(&s, n / 2), dt, 6.0).unwrap();
        let mid = &f[n / 2 + 50..n / 2 + n - 50];
        assert!(
            mid.iter().all(|v| v.abs() < 1e-3),
            "max {}",
            mid.iter().fold(0.0f64, |m, v| m.max(v.abs()))
        );
        // The filter's amplitude response at the cutoff, forward and back: |H|² = 1/2 for a
        // Butterworth at its (prewarped) cutoff.
        let s6: Vec<f64> = (0..4000)
            .map(|i| (2.0 * std::f64::consts::PI * 6.0 * i as f64 * 0.001).sin())
            .collect();
        let f6 = lowpass_butterworth3(&pad_odd(&s6, 2000), 0.001, 6.0).unwrap();
        let amp = f6[2000 + 1000..2000 + 3000]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((amp - 0.5).abs() < 2e-3, "gain at the cutoff {amp}");
    }

    /// The grounds of [`LOWEST_CUTOFF_CYCLES`]: below a cycle over the recording the
    /// filtered signal runs away from the data; at one cycle it stays within its range.
    #[test]
    fn a_cutoff_below_one_cycle_over_the_recording_runs_away_and_is_refused() {
        for (rate, n) in [(20.0, 40usize), (120.0, 240), (120.0, 600)] {
            let dt = 1.0 / rate;
            let duration = (n - 1) as f64 * dt;
            let s: Vec<f64> = (0..n)
                .map(|i| {
                    let t = i as f64 * dt;
                    0.5 * (2.0 * std::f64::consts::PI * 0.7 * t).sin() + 0.3 * t
                })
                .collect();
            let largest = s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let peak = |cycles: f64| {
                let f = lowpass_butterworth3(&pad_odd(&s, n / 2), dt, cycles / duration).unwrap();
                f[n / 2..n / 2 + n]
                    .iter()
                    .fold(0.0f64, |m, v| m.max(v.abs()))
                    / largest
            };
            assert!(peak(1.0) <= 1.0, "{n} samples at 1 cycle: {}", peak(1.0));
            assert!(peak(0.3) > 3.0, "{n} samples at 0.3 cycle: {}", peak(0.3));
            assert!(
                peak(0.01) > 30.0,
                "{n} samples at 0.01 cycle: {}",
                peak(0.01)
            );
            assert!(cutoff_problem(1.0 / duration, dt, duration).is_none());
            let refused = cutoff_problem(0.3 / duration, dt, duration).unwrap();
            assert!(refused.contains("below 1 cycle"), "{refused}");
        }
    }

    /// The grounds of [`HIGHEST_CUTOFF_FRACTION`]: a smooth signal (a trend and two slow
    /// sines), padded by half its length and filtered at fractions of the rate up to the
    /// highest, keeps its second differences within 10 % of the unfiltered signal's; at 0.48
    /// (what OpenSim's 0.49 rule allows) the filter's start-up rings them up many times over.
    #[test]
    fn the_highest_cutoff_keeps_the_second_differences() {
        let worst_ratio = |n: usize, fraction: f64, checked: bool| {
            let x: Vec<f64> = (0..n)
                .map(|i| {
                    let i = i as f64;
                    0.3 + 0.01 * i + 0.5 * (0.15 * i + 0.3).sin() + 0.2 * (0.05 * i).sin()
                })
                .collect();
            let second = |v: &[f64]| {
                (1..v.len() - 1)
                    .map(|i| (v[i + 1] - 2.0 * v[i] + v[i - 1]).abs())
                    .fold(0.0f64, f64::max)
            };
            let pad = n / 2;
            let filtered = if checked {
                lowpass_butterworth3(&pad_odd(&x, pad), 1.0, fraction).unwrap()
            } else {
                forward_backward(&pad_odd(&x, pad), 1.0, fraction)
            };
            second(&filtered[pad..pad + n]) / second(&x)
        };
        for n in [20, 40, 120] {
            for fraction in [0.1, 0.2, 0.3, 0.35, HIGHEST_CUTOFF_FRACTION] {
                let r = worst_ratio(n, fraction, true);
                assert!(r < 1.1, "{n} samples at {fraction} of the rate: ×{r}");
            }
            let r = worst_ratio(n, 0.48, false);
            assert!(r > 5.0, "{n} samples at 0.48 of the rate: ×{r}");
        }
        assert!(lowpass_butterworth3(&[1.0; 10], 1.0, 0.48).is_err());
        let message = lowpass_butterworth3(&[1.0; 10], 0.05, 15.0).unwrap_err();
        assert!(
            message.contains("cutoff 15 Hz is above 0.4 of the sampling rate (20 Hz)")
                && message.contains("at most 8 Hz"),
            "{message}"
        );
    }

    #[test]
    fn bad_arguments_are_errors() {
        assert!(lowpass_butterworth3(&[1.0, 2.0, 3.0], 0.01, 6.0).is_err());
        assert!(lowpass_butterworth3(&[1.0; 10], 0.0, 6.0).is_err());
        assert!(lowpass_butterworth3(&[1.0; 10], 0.01, -1.0).is_err());
        assert!(lowpass_butterworth3(&[1.0; 10], f64::INFINITY, 6.0).is_err());
        assert!(lowpass_butterworth3(&[1.0; 10], 0.01, f64::NAN).is_err());
        assert!(lowpass_butterworth3(&[1.0; 10], 0.01, f64::INFINITY).is_err());
    }

    #[test]
    fn the_grid_accumulates_like_opensim_and_is_bounded() {
        let g = accumulated_grid(0.0, 0.4, 0.1).unwrap();
        assert_eq!(g.len(), 5, "{g:?}");
        assert_eq!(
            g[3],
            0.1 + 0.1 + 0.1,
            "the drift of repeated addition is kept"
        );
        // 0.1 added three times is 0.30000000000000004 > 0.3: OpenSim's loop stops before.
        assert_eq!(accumulated_grid(0.0, 0.3, 0.1).unwrap().len(), 3);
        assert_eq!(accumulated_grid(1.0, 1.0, 0.5).unwrap(), vec![1.0]);
        for (first, last, dt) in [
            (0.0, 1.0, 0.0),
            (0.0, 1.0, -0.1),
            (0.0, 1.0, f64::NAN),
            (0.0, 1.0, f64::INFINITY),
            (0.0, f64::INFINITY, 0.1),
            (f64::NEG_INFINITY, 1.0, 0.1),
            (0.0, 1e308, 0.01),
            (0.0, 1.0, 1e-8),
        ] {
            let e = accumulated_grid(first, last, dt).unwrap_err();
            assert!(e.contains("s"), "{e}");
        }
        // Times so large that adding the step changes nothing: an error, not an endless loop.
        let e = accumulated_grid(1e20, 1e20 + 1e5, 1.0).unwrap_err();
        assert!(e.contains("resolution"), "{e}");
    }
}
