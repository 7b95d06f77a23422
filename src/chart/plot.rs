//! The chart's pictures: the error-against-time SVG (plotters) and the equal-time crops (a PNG
//! strip and a labelled SVG grid).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use base64::Engine as _;
use glam::Vec3;
use tracer::backend::Image;
use tracer::backend::Schedule;
use tracer::kernel::Strategy;

use super::{ChartBackend, Point};

/// The equal-time comparison: the reference and, for each line, its checkpoint with the most
/// samples within the time every line reached (the smallest final time). Writes them side by
/// side as a PNG strip (scaled up 3x, unlabelled, in the returned order) and as a labelled SVG
/// grid (a row per backend, the reference first; each crop titled with its strategy, backend,
/// samples and time; the crops are embedded PNGs at their rendered size, drawn enlarged with
/// `image-rendering: pixelated`). Returns the order, sample counts and times, for the caption.
pub(super) fn equal_time_strip(
    png: &Path,
    svg: &Path,
    size: u32,
    reference: &[Vec3],
    reference_label: &str,
    lines: &[Vec<Point>],
) -> Result<String> {
    let budget = lines.iter().filter_map(|l| l.last()).map(|p| p.seconds).fold(f64::INFINITY, f64::min);
    let picks: Vec<&Point> =
        lines.iter().filter_map(|l| l.iter().rev().find(|p| p.seconds <= budget).or(l.first())).collect();
    let scale = 3u32;
    let tile = size * scale;
    let count = picks.len() as u32 + 1;
    let mut pixels = vec![Vec3::ZERO; (tile * count * tile) as usize];
    let sources: Vec<&[Vec3]> =
        std::iter::once(reference).chain(picks.iter().map(|p| p.image.pixels.as_slice())).collect();
    for (i, src) in sources.iter().enumerate() {
        for y in 0..tile {
            for x in 0..tile {
                let s = src[((y / scale) * size + x / scale) as usize];
                pixels[(y * tile * count + i as u32 * tile + x) as usize] = s;
            }
        }
    }
    tracer::output::write_image(
        png,
        &Image { width: tile * count, height: tile, pixels },
        &tracer::output::Display::CLAMP,
    )?;
    let text = equal_time_svg(size, reference, reference_label, &picks, budget)?;
    std::fs::write(svg, text).with_context(|| format!("writing {}", svg.display()))?;
    Ok(picks
        .iter()
        .map(|p| format!("{} {}{} ({} spp, {:.3} s)", p.runtime(), p.strategy.name(), p.suffix(), p.spp, p.seconds))
        .collect::<Vec<_>>()
        .join(", "))
}

/// The labelled equal-time grid (see [`equal_time_strip`]).
fn equal_time_svg(
    size: u32,
    reference: &[Vec3],
    reference_label: &str,
    picks: &[&Point],
    budget: f64,
) -> Result<String> {
    // Rows: one per backend and schedule, in the order charted; the reference opens the first row.
    let mut rows: Vec<(String, Vec<&Point>)> = Vec::new();
    for p in picks {
        match rows.iter_mut().find(|(runtime, _)| *runtime == p.runtime()) {
            Some((_, row)) => row.push(p),
            None => rows.push((p.runtime(), vec![p])),
        }
    }
    if rows.is_empty() {
        rows.push((String::new(), Vec::new()));
    }
    let columns = 1 + rows.iter().map(|(_, r)| r.len()).max().unwrap_or(0);
    let (tile, gap, label, title) = (size.max(160), 10u32, 34u32, 30u32);
    let (width, height) =
        ((columns as u32 * (tile + gap) + gap).max(420), title + rows.len() as u32 * (label + tile + gap) + gap);
    let mut out = String::new();
    write!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" \
         width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" font-family=\"sans-serif\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{gap}\" y=\"20\" font-size=\"15\">Equal time: ≤ {} per line (the shortest line's total)</text>\n",
        seconds(budget)
    )?;
    let cell = |out: &mut String, row: usize, column: usize, heading: &str, detail: &str, pixels: &[Vec3]| {
        let x = gap + column as u32 * (tile + gap);
        let y = title + row as u32 * (label + tile + gap);
        let png = png_bytes(&Image { width: size, height: size, pixels: pixels.to_vec() })?;
        write!(
            out,
            "<text x=\"{x}\" y=\"{}\" font-size=\"13\" font-weight=\"bold\">{heading}</text>\n\
             <text x=\"{x}\" y=\"{}\" font-size=\"12\" fill=\"#444\">{detail}</text>\n\
             <image x=\"{x}\" y=\"{}\" width=\"{tile}\" height=\"{tile}\" preserveAspectRatio=\"none\" \
             style=\"image-rendering:pixelated\" xlink:href=\"data:image/png;base64,{}\"/>\n",
            y + 14,
            y + 29,
            y + label,
            base64::engine::general_purpose::STANDARD.encode(&png)
        )?;
        anyhow::Ok(())
    };
    cell(&mut out, 0, 0, "reference", reference_label, reference)?;
    for (r, (_, row)) in rows.iter().enumerate() {
        for (c, p) in row.iter().enumerate() {
            let heading = format!("{} · {}{}", p.strategy.name(), p.runtime(), p.suffix());
            let detail = format!("{} spp · {}", p.spp, seconds(p.seconds));
            cell(&mut out, r, c + 1, &heading, &detail, &p.image.pixels)?;
        }
    }
    out.push_str("</svg>\n");
    Ok(out)
}

/// A duration for a label, to about 3 significant digits.
fn seconds(s: f64) -> String {
    if s >= 1.0 {
        format!("{s:.2} s")
    } else if s >= 0.01 {
        format!("{s:.3} s")
    } else {
        format!("{:.2} ms", s * 1e3)
    }
}

/// An image as PNG bytes, tone-mapped like the CLI's PNG output.
fn png_bytes(image: &Image) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut png);
    image::ImageEncoder::write_image(
        encoder,
        &tracer::output::to_srgb8(image),
        image.width,
        image.height,
        image::ExtendedColorType::Rgb8,
    )
    .context("encoding a PNG")?;
    Ok(png)
}

/// A legend entry at `$at`: the line's stroke, 18 pixels long, and `$marker` (at pixel offsets
/// from `$at`: its middle is (9, 0)), hollow for a wavefront line, which tells the runtimes apart.
macro_rules! key {
    ($at:expr, $stroke_width:expr, $style:expr, $marker:expr) => {
        EmptyElement::at($at)
            + PathElement::new(vec![(0, 0), (18, 0)], ShapeStyle { stroke_width: $stroke_width, ..$style })
            + $marker
    };
}

pub(super) fn draw_chart(path: &Path, title: &str, lines: &[Vec<Point>]) -> Result<()> {
    use plotters::prelude::*;

    let root = SVGBackend::new(path, (1100, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 18))?;
    let (left, right) = root.split_horizontally(550);
    let all: Vec<&Point> = lines.iter().flatten().collect();
    let positive = |v: f64| v > 0.0 && v.is_finite();
    let range = |values: Vec<f64>| -> (f64, f64) {
        let lo = values.iter().copied().filter(|v| positive(*v)).fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().filter(|v| positive(*v)).fold(0.0, f64::max);
        if lo.is_finite() && hi > 0.0 {
            // Whole decades, so that every axis has at least two labelled powers of ten.
            (10f64.powf(lo.log10().floor()), 10f64.powf(hi.log10().ceil()).max(10.0 * lo))
        } else {
            (1e-6, 1.0)
        }
    };
    let (t0, t1) = range(all.iter().map(|p| p.seconds).collect());
    type Metric = fn(&Point) -> f64;
    let panels: [(&DrawingArea<SVGBackend, plotters::coord::Shift>, &str, Metric, f64); 2] =
        [(&left, "RMSE", |p| p.rmse, -0.5), (&right, "relMSE", |p| p.rel_mse, -1.0)];
    for (area, name, metric, slope) in panels {
        let (y0, y1) = range(all.iter().map(|p| metric(p)).collect());
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .caption(format!("{name} against render time"), ("sans-serif", 15))
            .build_cartesian_2d((t0..t1).log_scale(), (y0..y1).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("render time (s, log)")
            .y_desc(format!("{name} (log)"))
            .y_labels(8)
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        for line in lines {
            let Some(first) = line.first() else { continue };
            let color = match first.strategy {
                Strategy::Bsdf => RGBColor(214, 39, 40),
                Strategy::Nee => RGBColor(31, 119, 180),
                Strategy::Mis => RGBColor(44, 160, 44),
            };
            // A denoised line: its line's colour, darker (and labelled so).
            let color = if first.denoised { RGBColor(color.0 / 2, color.1 / 2, color.2 / 2) } else { color };
            let points: Vec<(f64, f64)> =
                line.iter().map(|p| (p.seconds, metric(p))).filter(|(t, e)| positive(*t) && positive(*e)).collect();
            let label = format!("{} {}{}", first.strategy.name(), first.runtime(), first.suffix());
            // A wavefront line: its runtime's line and markers, hollow (and the CPU's dashed).
            let wavefront = first.schedule == Schedule::Wavefront;
            let style = ShapeStyle { color: color.to_rgba(), filled: !wavefront, stroke_width: 2 };
            match first.backend {
                ChartBackend::Cpu if wavefront => {
                    chart
                        .draw_series(DashedLineSeries::new(points.clone(), 4, 3, style))?
                        .label(label)
                        .legend(move |(x, y)| key!((x, y), 2, style, Circle::new((9, 0), 3, style)));
                    chart.draw_series(points.iter().map(|p| Circle::new(*p, 3, style)))?;
                }
                ChartBackend::Cpu => {
                    chart
                        .draw_series(LineSeries::new(points.clone(), style))?
                        .label(label)
                        .legend(move |(x, y)| key!((x, y), 2, style, Circle::new((9, 0), 3, style)));
                    chart.draw_series(points.iter().map(|p| Circle::new(*p, 3, style)))?;
                }
                ChartBackend::Gl => {
                    chart
                        .draw_series(DashedLineSeries::new(points.clone(), 6, 4, style))?
                        .label(label)
                        .legend(move |(x, y)| key!((x, y), 1, style, TriangleMarker::new((9, 0), 4, style)));
                    chart.draw_series(points.iter().map(|p| TriangleMarker::new(*p, 4, style)))?;
                }
                ChartBackend::Wgpu => {
                    let (dash, gap) = if wavefront { (5, 5) } else { (10, 3) };
                    chart
                        .draw_series(DashedLineSeries::new(points.clone(), dash, gap, style))?
                        .label(label)
                        .legend(move |(x, y)| key!((x, y), 1, style, Rectangle::new([(6, -3), (12, 3)], style)));
                    // Squares: an element anchored at the point, drawn in pixel offsets.
                    chart.draw_series(
                        points.iter().map(|p| EmptyElement::at(*p) + Rectangle::new([(-3, -3), (3, 3)], style)),
                    )?;
                }
                ChartBackend::Web => {
                    chart
                        .draw_series(DashedLineSeries::new(points.clone(), 2, 3, style))?
                        .label(label)
                        .legend(move |(x, y)| key!((x, y), 1, style, Cross::new((9, 0), 4, style)));
                    chart.draw_series(points.iter().map(|p| Cross::new(*p, 4, style)))?;
                }
            }
        }
        // The guide: an unbiased estimator's RMSE falls as time^-1/2 (its MSE as time^-1),
        // drawn through the first CPU MIS point (or the first point at all).
        let anchor = lines
            .iter()
            .find(|l| {
                l.first().is_some_and(|p| {
                    p.backend == ChartBackend::Cpu && p.schedule == Schedule::Megakernel && p.strategy == Strategy::Mis
                })
            })
            .or(lines.first())
            .and_then(|l| l.first())
            .map(|p| (p.seconds, metric(p)))
            .filter(|(t, e)| positive(*t) && positive(*e));
        if let Some((ta, ea)) = anchor {
            let guide: Vec<(f64, f64)> = [t0, t1].iter().map(|t| (*t, ea * (t / ta).powf(slope))).collect();
            let gray = ShapeStyle { color: RGBColor(120, 120, 120).to_rgba(), filled: false, stroke_width: 1 };
            chart
                .draw_series(DashedLineSeries::new(guide, 3, 5, gray))?
                .label(if slope == -0.5 { "slope −½ (unbiased)" } else { "slope −1 (unbiased)" })
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], gray));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font(("sans-serif", 12))
            .draw()?;
    }
    root.present()?;
    Ok(())
}
