//! SVG plots (plotters): convergence series and the speed–accuracy trade on log–log axes, and
//! the histories a run leaves (`rbsm plot`).

use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

fn failed(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::io(path, std::io::Error::other(e.to_string()))
}

/// The range of positive values, widened by `factor` on both sides.
fn range(values: impl Iterator<Item = f64>, factor: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| *v > 0.0 && v.is_finite())
        .fold((f64::MAX, f64::MIN), |a, v| (a.0.min(v), a.1.max(v)));
    if lo > hi {
        return 0.1..10.0;
    }
    lo / factor..hi * factor
}

/// A log axis over `range` whose labels and grid lines are at `m × 10^k`: labelled at
/// `m` = 1, 2 and 5 (only `m` = 1 over more than three decades), light lines at every
/// `m` = 1..9. plotters' own log axis drew the next decade's line twice and a hundred light lines
/// in each decade, bunched at its top (a grey band on `tradeoff.svg`).
fn log_axis(
    range: std::ops::Range<f64>,
) -> plotters::coord::combinators::WithKeyPoints<LogCoord<f64>> {
    let (lo, hi) = (range.start, range.end);
    let marks = |mantissas: &[f64]| -> Vec<f64> {
        let mut points = Vec::new();
        let mut decade = 10f64.powf(lo.log10().floor());
        while decade <= hi {
            points.extend(
                mantissas
                    .iter()
                    .map(|m| m * decade)
                    .filter(|x| (lo..=hi).contains(x)),
            );
            decade *= 10.0;
        }
        points
    };
    let labelled: &[f64] = if hi / lo > 1e3 {
        &[1.0]
    } else {
        &[1.0, 2.0, 5.0]
    };
    range
        .log_scale()
        .with_key_points(marks(labelled))
        .with_light_points(marks(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]))
}

/// Named series of `(x, y)` as lines with markers on log–log axes (non-positive points are
/// left out).
///
/// # Errors
/// plotters cannot draw the chart, or `path` cannot be written.
pub fn log_log(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
) -> Result<()> {
    svg_file(path, (720, 480), |root| {
        let all = || series.iter().flat_map(|s| s.1.iter().copied());
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                log_axis(range(all().map(|p| p.0), 1.3)),
                log_axis(range(all().map(|p| p.1), 2.0)),
            )
            .map_err(|e| failed(path, e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .x_label_formatter(&|x| tick(*x))
            .y_label_formatter(&|y| tick(*y))
            .draw()
            .map_err(|e| failed(path, e))?;
        for (i, (name, pts)) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<_> = pts
                .iter()
                .copied()
                .filter(|p| p.0 > 0.0 && p.1 > 0.0)
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(|e| failed(path, e))?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| failed(path, e))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| failed(path, e))?;
        Ok(())
    })
}

/// Named series of `(x, y)` as lines on linear axes (a load–displacement curve over its
/// reference).
///
/// # Errors
/// plotters cannot draw the chart, or `path` cannot be written.
pub fn lines(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
) -> Result<()> {
    svg_file(path, (760, 460), |root| {
        panel(root, path, title, x_label, y_label, series, false)
    })
}

/// Error against wall time of the points `(wall_s, error, on_front, label)`: every point as a
/// grey dot, the Pareto front as a line through red diamonds labelled with their settings.
///
/// # Errors
/// plotters cannot draw the chart, or `path` cannot be written.
pub fn pareto(path: &Path, title: &str, points: &[(f64, f64, bool, String)]) -> Result<()> {
    svg_file(path, (820, 540), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                log_axis(range(points.iter().map(|p| p.0), 1.5)),
                log_axis(range(points.iter().map(|p| p.1), 2.0)),
            )
            .map_err(|e| failed(path, e))?;
        chart
            .configure_mesh()
            .x_desc("wall time (s)")
            .y_desc("relative error")
            .x_label_formatter(&|x| tick(*x))
            .y_label_formatter(&|y| tick(*y))
            .draw()
            .map_err(|e| failed(path, e))?;
        chart
            .draw_series(
                points
                    .iter()
                    .map(|p| Circle::new((p.0, p.1), 3, RGBColor(120, 120, 120).filled())),
            )
            .map_err(|e| failed(path, e))?
            .label("run")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(120, 120, 120).filled()));
        let mut front: Vec<(f64, f64)> =
            points.iter().filter(|p| p.2).map(|p| (p.0, p.1)).collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(front.clone(), RED.stroke_width(2)))
            .map_err(|e| failed(path, e))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
        for p in points.iter().filter(|p| p.2) {
            chart
                .draw_series([TriangleMarker::new((p.0, p.1), 6, RED.filled())])
                .map_err(|e| failed(path, e))?;
            chart
                .draw_series([Text::new(
                    p.3.clone(),
                    (p.0, p.1),
                    ("sans-serif", 11).into_font().color(&BLACK),
                )])
                .map_err(|e| failed(path, e))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| failed(path, e))?;
        Ok(())
    })
}

/// One column of a CSV file of numbers: its header and its values.
#[derive(Debug, Clone)]
pub struct Column {
    /// The header of the column.
    pub name: String,
    /// The values, top to bottom.
    pub values: Vec<f64>,
}

/// An error naming `path` and what is wrong with its contents.
fn invalid(path: &Path, message: &str) -> Error {
    Error::io(
        path,
        std::io::Error::new(std::io::ErrorKind::InvalidData, message.to_string()),
    )
}

/// The largest file `plot` reads (bytes): a history or fraction series larger than this is
/// thinned with `output.every` before it can be drawn.
pub const MAX_CSV_BYTES: u64 = 1 << 30;

/// Reads a CSV file of numbers under one header line, as the runs write them (to plot it, or a
/// history to resume); a file that is not a regular one or is larger than [`MAX_CSV_BYTES`] is
/// refused before it is read.
///
/// # Errors
/// `path` cannot be read, is not a regular file, is larger than [`MAX_CSV_BYTES`] or is not UTF-8;
/// or it has no header line, a row with another number of fields than the header, or a field that
/// is not a number (the error names the line).
pub fn read_csv(path: &Path) -> Result<Vec<Column>> {
    let text =
        crate::input::scene::read_text_limited(path, MAX_CSV_BYTES, "a CSV file of numbers")?;
    let bad = |line: usize, message: String| invalid(path, &format!("line {line}: {message}"));
    let mut lines = text.lines();
    let mut columns: Vec<Column> = lines
        .next()
        .ok_or_else(|| bad(1, "empty file, a header line was expected".into()))?
        .split(',')
        .map(|h| Column {
            name: h.trim().to_string(),
            values: Vec::new(),
        })
        .collect();
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != columns.len() {
            return Err(bad(
                i + 2,
                format!(
                    "{} fields where the header has {}",
                    fields.len(),
                    columns.len()
                ),
            ));
        }
        for (c, f) in columns.iter_mut().zip(fields) {
            c.values.push(f.trim().parse().map_err(|_| {
                bad(
                    i + 2,
                    format!("`{f}` in column `{}` is not a number", c.name),
                )
            })?);
        }
    }
    Ok(columns)
}

/// A tick label with at most six significant digits and no trailing zeros, so that float noise
/// (`0.30000000000000004`) never shows and close ticks stay apart: plain decimals between 1e-3
/// and 1e4, else scientific.
fn tick(x: f64) -> String {
    if x == 0.0 || (1e-3..1e4).contains(&x.abs()) {
        // Zero has no magnitude: `log10` would be −∞, and `5 − i32::MIN` overflow.
        let decimals = match x {
            0.0 => 0,
            _ => (5 - x.abs().log10().floor() as i32).max(0) as usize,
        };
        let s = format!("{x:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{x:.5e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        format!("{mantissa}e{exponent}")
    }
}

/// Lines of `(x, y)` series on linear axes in `area`; with `log_y`, `y` is drawn as `log10 y`
/// (non-positive values left out) and labelled in powers of ten.
fn panel(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
    log_y: bool,
) -> Result<()> {
    let series: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(n, pts)| {
            (
                *n,
                pts.iter()
                    .filter(|p| !log_y || p.1 > 0.0)
                    .map(|&(x, y)| (x, if log_y { y.log10() } else { y }))
                    .filter(|p| p.0.is_finite() && p.1.is_finite())
                    .collect(),
            )
        })
        .collect();
    let all = || series.iter().flat_map(|s| s.1.iter().copied());
    let bounds = |f: fn((f64, f64)) -> f64| {
        let (lo, hi) = all()
            .map(f)
            .fold((f64::MAX, f64::MIN), |a, v| (a.0.min(v), a.1.max(v)));
        if lo > hi {
            (0.0, 1.0)
        } else {
            let pad = if hi > lo {
                0.05 * (hi - lo)
            } else {
                lo.abs().max(1e-30) * 0.1
            };
            (lo - pad, hi + pad)
        }
    };
    let ((x0, x1), (y0, y1)) = (bounds(|p| p.0), bounds(|p| p.1));
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| failed(path, e))?;
    // On a log axis the ticks fall between round values: three significant digits suffice.
    let round3 = |v: f64| {
        if v > 0.0 {
            let k = 10f64.powi(v.log10().floor() as i32 - 2);
            (v / k).round() * k
        } else {
            v
        }
    };
    // A tick meant to be 0 can come out as round-off (-6.9e-18 on a span of 0.05): snap it.
    let snap = |v: f64, span: f64| if v.abs() <= 1e-9 * span { 0.0 } else { v };
    let y_format = |y: &f64| {
        if log_y {
            tick(round3(10f64.powf(*y)))
        } else {
            tick(snap(*y, y1 - y0))
        }
    };
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|x| tick(snap(*x, x1 - x0)))
        .y_label_formatter(&y_format)
        .draw()
        .map_err(|e| failed(path, e))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(|e| failed(path, e))?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| failed(path, e))?;
    Ok(())
}

/// Draws the SVG of `size` pixels that `draw` fills, and writes it to `path`
/// ([`crate::output::write_atomic`]).
fn svg_file(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend, plotters::coord::Shift>) -> Result<()>,
) -> Result<()> {
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| failed(path, e))?;
        draw(&root)?;
        root.present().map_err(|e| failed(path, e))?;
    }
    crate::output::write_atomic(path, text.as_bytes())
}

/// The pictures [`histories`] draws from a run's `history.csv`: `energies.svg`, `probes.svg`
/// (a run removes them from its folder with its other outputs).
pub const RUN_PLOTS: [&str; 2] = ["energies.svg", "probes.svg"];

/// Draws the histories that runs left in `dir`, as SVG beside them, and returns the files written:
/// - `history.csv` of `rbsm run`: `energies.svg` (each energy or work that is not zero
///   throughout, J, against `t`) and `probes.svg` (one panel per probe, and two per moving
///   clamp: its displacement and its reaction);
/// - `fraction_F.csv` of `rbsm stability --out`: `stability.svg`, the stored (kinetic +
///   elastic) energy of each run relative to the first it stored, on a log scale: bounded below
///   `Δt_crit`, growing geometrically (a straight line) above it until the guard stops the run.
///
/// # Errors
/// `dir` cannot be listed or holds neither `history.csv` nor a `fraction_F.csv`; the history is not
/// a CSV of numbers ([`read_csv`]) with `t` as first column, or a fraction series has no `stored`
/// column; or a plot cannot be drawn or written.
pub fn histories(dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut written = Vec::new();
    let history = dir.join("history.csv");
    if history.exists() {
        written.extend(run_plots(dir, &history)?);
    }
    written.extend(stability_plot(dir)?);
    if written.is_empty() {
        return Err(invalid(
            dir,
            "holds neither history.csv (from `rbsm run`) nor fraction_F.csv \
            files (from `rbsm stability --out`)",
        ));
    }
    Ok(written)
}

/// `energies.svg` and, when the run had probes or moving clamps, `probes.svg` from a run's
/// `history` in `dir`; returns the files written. The clamps' columns and the probes' units are
/// read from the run's `summary.json` when it is there.
fn run_plots(dir: &Path, history: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut written = Vec::new();
    let columns = read_csv(history)?;
    let t = &columns
        .first()
        .filter(|c| c.name == "t")
        .ok_or_else(|| invalid(history, "the first column must be `t`"))?
        .values;
    let pairs = |c: &Column| {
        t.iter()
            .copied()
            .zip(c.values.iter().copied())
            .collect::<Vec<_>>()
    };
    let is_energy = |c: &Column| crate::output::energy_columns().any(|e| e == c.name);
    let energies: Vec<(&str, Vec<(f64, f64)>)> = columns
        .iter()
        .filter(|c| is_energy(c) && c.values.iter().any(|v| *v != 0.0))
        .map(|c| (c.name.as_str(), pairs(c)))
        .collect();
    let path = dir.join(RUN_PLOTS[0]);
    svg_file(&path, (820, 480), |root| {
        panel(
            root,
            &path,
            "energies",
            "t (s)",
            "energy (J)",
            &energies,
            false,
        )
    })?;
    written.push(path);
    let probes: Vec<&Column> = columns[1..].iter().filter(|c| !is_energy(c)).collect();
    if !probes.is_empty() {
        // The clamps and the probes' units from the run's summary, when it is there.
        let summary: serde_json::Value = crate::input::scene::read_text_limited(
            &dir.join("summary.json"),
            MAX_CSV_BYTES,
            "a run's summary",
        )
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_default();
        let listed = |key: &str| summary[key].as_array().cloned().unwrap_or_default();
        // `(title, axis)` of a column: a moving clamp's displacement or reaction, or a probe.
        let clamps = listed("clamps");
        let probe_units = listed("probes");
        let label = |name: &str| {
            for clamp in clamps.iter().filter_map(|c| c["name"].as_str()) {
                let [disp, force] = crate::output::clamp_columns(clamp);
                if name == disp {
                    return (
                        format!("clamp {clamp}: its displacement along its velocity"),
                        format!("{name} (m)"),
                    );
                }
                if name == force {
                    return (
                        format!("clamp {clamp}: its reaction along its velocity"),
                        format!("{name} (N)"),
                    );
                }
            }
            let unit = probe_units
                .iter()
                .find(|p| p["name"] == name)
                .and_then(|p| p["unit"].as_str());
            let unit = match unit {
                Some("1") => "strain".to_string(),
                Some(u) => format!("({u})"),
                None => "(m, rad or strain)".to_string(),
            };
            (format!("probe {name}"), format!("{name} {unit}"))
        };
        let path = dir.join(RUN_PLOTS[1]);
        svg_file(&path, (820, 260 * probes.len() as u32), |root| {
            for (area, c) in root.split_evenly((probes.len(), 1)).iter().zip(&probes) {
                let (title, axis) = label(&c.name);
                panel(
                    area,
                    &path,
                    &title,
                    "t (s)",
                    &axis,
                    &[(c.name.as_str(), pairs(c))],
                    false,
                )?;
            }
            Ok(())
        })?;
        written.push(path);
    }
    Ok(written)
}

/// `stability.svg` from the `fraction_F.csv` files of `rbsm stability --out` in `dir`, when it
/// has any.
fn stability_plot(dir: &Path) -> Result<Option<std::path::PathBuf>> {
    let mut fractions = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let p = entry.map_err(|e| Error::io(dir, e))?.path();
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if let Some(f) = name
            .strip_prefix("fraction_")
            .and_then(|n| n.strip_suffix(".csv"))
        {
            fractions.push((f.to_string(), p.clone()));
        }
    }
    if fractions.is_empty() {
        return Ok(None);
    }
    fractions.sort_by(|a, b| {
        a.0.parse::<f64>()
            .unwrap_or(f64::MAX)
            .total_cmp(&b.0.parse::<f64>().unwrap_or(f64::MAX))
    });
    let mut series = Vec::new();
    for (f, p) in &fractions {
        let c = read_csv(p)?;
        let stored = c
            .iter()
            .find(|c| c.name == "stored")
            .ok_or_else(|| invalid(p, "expected the columns t,total,stored"))?;
        // Relative to the first energy stored: a run loaded from rest starts at 0 J.
        let s0 = stored
            .values
            .iter()
            .copied()
            .find(|e| *e > 0.0)
            .unwrap_or(1.0);
        series.push((
            format!("dt = {f} Δt_crit"),
            c[0].values
                .iter()
                .zip(&stored.values)
                .map(|(t, e)| (*t, e / s0))
                .collect::<Vec<_>>(),
        ));
    }
    let series: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(n, s)| (n.as_str(), s.clone()))
        .collect();
    // A run above the limit stops within a few steps: the second panel shows those steps.
    let shortest = series
        .iter()
        .map(|s| s.1.last().map_or(0.0, |p| p.0))
        .fold(f64::INFINITY, f64::min);
    let early: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(n, s)| {
            (
                *n,
                s.iter()
                    .copied()
                    .filter(|p| p.0 <= 1.5 * shortest)
                    .collect(),
            )
        })
        .collect();
    let path = dir.join("stability.svg");
    svg_file(&path, (820, 900), |root| {
        let areas = root.split_evenly((2, 1));
        panel(
            &areas[0],
            &path,
            "kinetic + elastic energy at fractions of Δt_crit",
            "t (s)",
            "E / E(first stored)",
            &series,
            true,
        )?;
        panel(
            &areas[1],
            &path,
            "the first steps, until the shortest run stopped",
            "t (s)",
            "E / E(first stored)",
            &early,
            true,
        )
    })?;
    Ok(Some(path))
}

#[cfg(test)]
mod tests {
    use super::{log_axis, tick};

    #[test]
    fn log_axes_mark_each_value_once() {
        use plotters::coord::ranged1d::{BoldPoints, LightPoints, Ranged};
        // Two decades, as `rbsm tradeoff`'s errors: 1, 2 and 5 labelled, every m × 10^k lined.
        let axis = log_axis(3e-4..3e-2);
        let bold = axis.key_points(BoldPoints(10));
        let light = axis.key_points(LightPoints::new(10, 100));
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * y)
        };
        assert!(
            close(&bold, &[5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2]),
            "{bold:?}"
        );
        assert_eq!(light.len(), 7 + 9 + 3, "{light:?}");
        assert!(light.windows(2).all(|w| w[1] > w[0] * 1.05), "{light:?}");
        // Over more than three decades, the decades alone are labelled.
        let bold = log_axis(2e-7..3e-2).key_points(BoldPoints(10));
        assert!(close(&bold, &[1e-6, 1e-5, 1e-4, 1e-3, 1e-2]), "{bold:?}");
    }

    #[test]
    fn ticks_show_no_float_noise_and_stay_distinct() {
        assert_eq!(tick(0.1 + 0.2), "0.3");
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(1500.0), "1500");
        assert_eq!(tick(2.5e-7), "2.5e-7");
        assert_eq!(tick(-0.00125), "-0.00125");
        // Ticks 1e-5 apart near 1e-3 used to print alike at four decimals.
        assert_ne!(tick(0.00121), tick(0.00122));
        assert_ne!(tick(1.0e-4), tick(1.5e-4));
    }
}
