//! The convergence plot: relative RMSE against time on log-log axes, one curve per variant
//! with the spread of its runs, the fitted slope in the legend (plotters).

use plotters::prelude::*;
use std::path::Path;

/// One curve: (seconds, mean, lowest, highest relative RMSE over runs) per checkpoint.
pub struct Curve {
    pub label: String,
    pub points: Vec<(f64, f64, f64, f64)>,
    pub slope: Option<f64>,
}

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // DejaVu Sans (Bitstream Vera license, assets/fonts/), so plots need no system font.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
        );
    });
}

/// A tick label with two significant digits: 0.05, 0.3, 12, 1500.
fn sig2(v: f64) -> String {
    if v <= 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if (v - v.round()).abs() < 1e-9 * v {
        return format!("{v:.0}");
    }
    let digits = (1 - v.log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// Writes the plot as a PNG.
pub fn plot(path: &Path, title: &str, curves: &[Curve]) -> Result<(), super::ConvergeError> {
    register_font();
    let all: Vec<(f64, f64)> = curves
        .iter()
        .flat_map(|c| c.points.iter().flat_map(|p| [(p.0, p.2), (p.0, p.3)]))
        .filter(|(t, e)| *t > 0.0 && *e > 0.0 && e.is_finite())
        .collect();
    if all.is_empty() {
        return Err(super::ConvergeError::NoCheckpoints);
    }
    let (t0, t1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (e0, e1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    // Drawn into memory and encoded by our own `image` (plotters' encoder would bring a
    // second version of the crate), written atomically like every output.
    let (width, height) = (900u32, 600u32);
    let mut rgb = vec![0u8; (width * height * 3) as usize];
    draw(&mut rgb, (width, height), title, curves, (t0, t1), (e0, e1))
        .map_err(|e| super::ConvergeError::Draw(e.to_string()))?;
    crate::output::write::write_rgb8_png(path, width, height, rgb)?;
    Ok(())
}

/// Draws the plot into an RGB buffer of `size`.
fn draw<'a>(
    rgb: &'a mut [u8],
    size: (u32, u32),
    title: &str,
    curves: &[Curve],
    (t0, t1): (f64, f64),
    (e0, e1): (f64, f64),
) -> Result<(), DrawingAreaErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>> {
    let root = BitMapBackend::with_buffer(rgb, size).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(46)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (t0 / 1.2..t1 * 1.2).log_scale(),
            (e0 / 1.5..e1 * 1.5).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("render time (s)")
        .y_desc("relative RMSE")
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&|v| sig2(*v))
        .y_label_formatter(&|v| format!("{}%", sig2(*v * 100.0)))
        .light_line_style(TRANSPARENT)
        .label_style(("sans-serif", 15))
        .draw()?;
    for (i, c) in curves.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        if c.points.iter().any(|p| p.2 != p.3) {
            let band: Vec<(f64, f64)> = c
                .points
                .iter()
                .map(|p| (p.0, p.3))
                .chain(c.points.iter().rev().map(|p| (p.0, p.2)))
                .collect();
            chart.draw_series(std::iter::once(Polygon::new(band, color.mix(0.15))))?;
        }
        let label = match c.slope {
            Some(s) => format!("{} (slope {s:.2})", c.label),
            None => c.label.clone(),
        };
        chart
            .draw_series(LineSeries::new(
                c.points.iter().map(|p| (p.0, p.1)),
                color.stroke_width(2),
            ))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(
            c.points
                .iter()
                .map(|p| Circle::new((p.0, p.1), 3, color.filled())),
        )?;
    }
    // The slope an unbiased Monte Carlo estimator approaches: error ∝ time^-1/2.
    let guide: Vec<(f64, f64)> = [t0, t1]
        .iter()
        .map(|t| {
            (
                *t,
                curves[0].points[0].1 * (t / curves[0].points[0].0).powf(-0.5),
            )
        })
        .collect();
    chart
        .draw_series(LineSeries::new(guide, BLACK.mix(0.4).stroke_width(1)))?
        .label("slope -0.5")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.4)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()?;
    root.present()?;
    Ok(())
}
