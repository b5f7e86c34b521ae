//! SVG plots on log–log axes: convergence series and the speed–accuracy trade.

use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

fn failed(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::io(path, std::io::Error::other(e.to_string()))
}

/// The range of positive values, widened by `factor` on both sides.
fn range(values: impl Iterator<Item = f64>, factor: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values.filter(|v| *v > 0.0 && v.is_finite()).fold((f64::MAX, f64::MIN), |a, v| (a.0.min(v), a.1.max(v)));
    if lo > hi {
        return 0.1..10.0;
    }
    lo / factor..hi * factor
}

/// Named series of `(x, y)` as lines with markers on log–log axes (non-positive points are
/// left out).
pub fn log_log(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[(&str, Vec<(f64, f64)>)]) -> Result<()> {
    let root = SVGBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| failed(path, e))?;
    let all = || series.iter().flat_map(|s| s.1.iter().copied());
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(range(all().map(|p| p.0), 1.3).log_scale(), range(all().map(|p| p.1), 2.0).log_scale())
        .map_err(|e| failed(path, e))?;
    chart.configure_mesh().x_desc(x_label).y_desc(y_label).y_label_formatter(&|y| format!("{y:.0e}")).draw().map_err(|e| failed(path, e))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let pts: Vec<_> = pts.iter().copied().filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(|e| failed(path, e))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled()))).map_err(|e| failed(path, e))?;
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|e| failed(path, e))?;
    root.present().map_err(|e| failed(path, e))
}

/// Error against wall time of the points `(wall_s, error, on_front, label)`: every point as a
/// grey dot, the Pareto front as a line through red diamonds labelled with their settings.
pub fn pareto(path: &Path, title: &str, points: &[(f64, f64, bool, String)]) -> Result<()> {
    let root = SVGBackend::new(path, (820, 540)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| failed(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(range(points.iter().map(|p| p.0), 1.5).log_scale(), range(points.iter().map(|p| p.1), 2.0).log_scale())
        .map_err(|e| failed(path, e))?;
    chart
        .configure_mesh()
        .x_desc("wall time (s)")
        .y_desc("relative error")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()
        .map_err(|e| failed(path, e))?;
    chart
        .draw_series(points.iter().map(|p| Circle::new((p.0, p.1), 3, RGBColor(120, 120, 120).filled())))
        .map_err(|e| failed(path, e))?
        .label("run")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(120, 120, 120).filled()));
    let mut front: Vec<(f64, f64)> = points.iter().filter(|p| p.2).map(|p| (p.0, p.1)).collect();
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
            .draw_series([Text::new(p.3.clone(), (p.0, p.1), ("sans-serif", 11).into_font().color(&BLACK))])
            .map_err(|e| failed(path, e))?;
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|e| failed(path, e))?;
    root.present().map_err(|e| failed(path, e))
}
