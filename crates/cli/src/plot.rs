//! PNG plots of runs: the field from above with the trajectory (the paper's whole-field figure) and
//! lateral/heading error against distance travelled (its recovery figure). Coordinates are in the
//! simulator's `world` frame (= `odom` at the start of the run), metres.

use std::path::Path;
use std::sync::Once;

use anyhow::{Context, Result, anyhow};
use plotters::prelude::*;
use plotters::style::FontStyle;

/// DejaVu Sans, vendored so plots render on a machine without fontconfig (see assets/DejaVuSans.LICENSE).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn ensure_font() -> Result<()> {
    let mut result = Ok(());
    REGISTER.call_once(|| {
        result = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the vendored DejaVu Sans font could not be parsed"));
    });
    result
}

/// What the top view shows, all in the world frame, metres.
pub struct TopView<'a> {
    /// Title drawn above the plot.
    pub title: &'a str,
    /// True row centre polylines.
    pub rows: &'a [Vec<[f64; 2]>],
    /// The robot's true trajectory.
    pub trajectory: &'a [[f64; 2]],
    /// Detected row segments `[x1, y1, x2, y2]`, already mapped into the world frame.
    pub detected: &'a [[f64; 4]],
}

fn bounds(points: impl Iterator<Item = [f64; 2]>) -> Option<([f64; 2], [f64; 2])> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in points.filter(|p| p[0].is_finite() && p[1].is_finite()) {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo[0] <= hi[0]).then_some((lo, hi))
}

/// Draws the field from above with the trajectory and detected rows into a PNG at `path`.
pub fn top_view(path: &Path, view: &TopView<'_>) -> Result<()> {
    ensure_font()?;
    let all = view.rows.iter().flatten().copied().chain(view.trajectory.iter().copied());
    let (lo, hi) = bounds(all).context("nothing to plot: no rows and no trajectory")?;
    let margin = 1.0;
    let (w_m, h_m) = (hi[0] - lo[0] + 2.0 * margin, hi[1] - lo[1] + 2.0 * margin);
    // Equal axes where the field's aspect allows it; long fields get a taller strip so rows stay visible.
    let width = 1600u32;
    let height = ((width as f64 * h_m / w_m) as u32 + 120).clamp(400, 1200);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(view.title, ("sans-serif", 28))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d((lo[0] - margin)..(hi[0] + margin), (lo[1] - margin)..(hi[1] + margin))?;
    chart.configure_mesh().x_desc("x (m)").y_desc("y (m)").label_style(("sans-serif", 16)).draw()?;
    let crop = RGBColor(60, 160, 60);
    for (i, row) in view.rows.iter().enumerate() {
        let series =
            chart.draw_series(LineSeries::new(row.iter().map(|p| (p[0], p[1])), crop.stroke_width(2)))?;
        if i == 0 {
            series.label("true rows").legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], crop));
        }
    }
    let detected = RGBColor(30, 90, 220);
    if !view.detected.is_empty() {
        chart
            .draw_series(
                view.detected.iter().map(|s| {
                    PathElement::new([(s[0], s[1]), (s[2], s[3])], detected.mix(0.35).stroke_width(1))
                }),
            )?
            .label("detected rows")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], detected));
    }
    chart
        .draw_series(LineSeries::new(view.trajectory.iter().map(|p| (p[0], p[1])), RED.stroke_width(2)))?
        .label("robot trajectory")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .draw()?;
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Errors along a run, sampled together.
pub struct ErrorSeries<'a> {
    /// Title drawn above the plots.
    pub title: &'a str,
    /// Distance travelled at each sample, m.
    pub distance_m: &'a [f64],
    /// Signed lateral error to the true centre line, cm.
    pub lateral_cm: &'a [f64],
    /// Signed heading error to the true rows, degrees.
    pub heading_deg: &'a [f64],
}

fn range_of(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.1).max(0.5);
    (lo - pad, hi + pad)
}

/// Draws lateral (top) and heading (bottom) error against distance travelled into a PNG at `path`.
pub fn errors_vs_distance(path: &Path, s: &ErrorSeries<'_>) -> Result<()> {
    ensure_font()?;
    let root = BitMapBackend::new(path, (1400, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(s.title, ("sans-serif", 28))?;
    let (top, bottom) = root.split_vertically(380);
    let d_max = s.distance_m.iter().copied().filter(|d| d.is_finite()).fold(1.0, f64::max);
    for (area, values, label, color) in
        [(top, s.lateral_cm, "lateral error (cm)", BLUE), (bottom, s.heading_deg, "heading error (deg)", RED)]
    {
        let (lo, hi) = range_of(values);
        let mut chart = ChartBuilder::on(&area)
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..d_max, lo..hi)?;
        chart
            .configure_mesh()
            .x_desc("distance travelled (m)")
            .y_desc(label)
            .label_style(("sans-serif", 16))
            .draw()?;
        chart.draw_series(LineSeries::new(
            s.distance_m
                .iter()
                .zip(values)
                .filter(|(d, v)| d.is_finite() && v.is_finite())
                .map(|(d, v)| (*d, *v)),
            color.stroke_width(2),
        ))?;
        chart.draw_series(LineSeries::new([(0.0, 0.0), (d_max, 0.0)], BLACK.mix(0.4)))?;
    }
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_render_to_png_files() {
        let dir = std::env::temp_dir().join(format!("croprow-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rows: Vec<Vec<[f64; 2]>> =
            (0..4).map(|r| (0..=30).map(|x| [x as f64, r as f64 * 0.75]).collect()).collect();
        let trajectory: Vec<[f64; 2]> = (0..=300).map(|i| [i as f64 * 0.1, 1.125]).collect();
        let detected = [[1.0, 0.75, 4.0, 0.76], [1.0, 1.5, 4.0, 1.49]];
        let top = dir.join("top.png");
        top_view(&top, &TopView { title: "test", rows: &rows, trajectory: &trajectory, detected: &detected })
            .unwrap();
        let d: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let lat: Vec<f64> = d.iter().map(|x| 30.0 * (-x).exp()).collect();
        let head: Vec<f64> = d.iter().map(|x| 8.0 * (-x).exp()).collect();
        let err = dir.join("err.png");
        errors_vs_distance(
            &err,
            &ErrorSeries { title: "t", distance_m: &d, lateral_cm: &lat, heading_deg: &head },
        )
        .unwrap();
        for p in [top, err] {
            let bytes = std::fs::read(&p).unwrap();
            assert!(
                bytes.len() > 5_000 && bytes.starts_with(b"\x89PNG"),
                "{} is not a real PNG",
                p.display()
            );
        }
        if std::env::var_os("CROPROW_KEEP_PLOTS").is_none() {
            std::fs::remove_dir_all(&dir).ok();
        }
    }

    #[test]
    fn empty_top_view_is_an_error_not_a_panic() {
        let path = std::env::temp_dir().join("croprow-empty-top.png");
        assert!(top_view(&path, &TopView { title: "", rows: &[], trajectory: &[], detected: &[] }).is_err());
    }
}
