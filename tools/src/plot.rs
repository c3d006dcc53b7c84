//! Log-log plots of time against error for the reports, as SVG and PNG (plotters): a light
//! grid, axis labels with units, ticks at 1, 2 and 5 x 10^k, the legend beside the data (not on
//! it), one colour per case and one marker shape per mesh family, and the reference runs marked.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

/// One point: its series ("<case>, <mesh family>"), x, y, and whether it is a reference run
/// (drawn ringed).
#[derive(Clone, Debug)]
pub struct Point {
    pub series: String,
    pub x: f64,
    pub y: f64,
    pub reference: bool,
}

/// A log-log plot of points.
pub struct LogLog<'a> {
    pub caption: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub points: Vec<Point>,
    /// What a ringed point is (the legend's entry for it).
    pub reference_label: Option<&'a str>,
}

/// The plot's size without its legend, and the height of a legend row (the legend sits below
/// the data, so that series names of any length fit).
const SIZE: (u32, u32) = (1000, 560);
const LEGEND_ROW: u32 = 22;
const FONT: &str = "sans-serif";

impl LogLog<'_> {
    /// Writes `<stem>.svg` and `<stem>.png`.
    pub fn write(&self, stem: &Path) -> Result<(), Box<dyn std::error::Error>> {
        register_font()?;
        let size = self.size();
        self.draw(SVGBackend::new(&stem.with_extension("svg"), size).into_drawing_area())?;
        let mut buffer = vec![0u8; (size.0 * size.1 * 3) as usize];
        self.draw(BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area())?;
        let image = image::RgbImage::from_raw(size.0, size.1, buffer).ok_or("plot buffer size")?;
        image.save(stem.with_extension("png"))?;
        Ok(())
    }

    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>) -> Result<(), Box<dyn std::error::Error>>
    where
        B::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (plot, legend) = root.split_vertically(SIZE.1);
        let range = |v: &mut dyn Iterator<Item = f64>| {
            let (lo, hi) =
                v.filter(|x| *x > 0.0 && x.is_finite()).fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
            if lo.is_finite() {
                (lo / 1.6, hi * 1.6)
            } else {
                (0.1, 10.0)
            }
        };
        let (x0, x1) = range(&mut self.points.iter().map(|p| p.x));
        let (y0, y1) = range(&mut self.points.iter().map(|p| p.y));
        let mut chart = ChartBuilder::on(&plot)
            .caption(self.caption, (FONT, 20))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (x0..x1).log_scale().with_key_points(ticks(x0, x1)).with_light_points(minor_ticks(x0, x1)),
                (y0..y1).log_scale().with_key_points(ticks(y0, y1)).with_light_points(minor_ticks(y0, y1)),
            )?;
        chart
            .configure_mesh()
            .bold_line_style(RGBColor(200, 200, 200).stroke_width(1))
            .light_line_style(RGBColor(238, 238, 238).stroke_width(1))
            .axis_style(RGBColor(90, 90, 90))
            .x_desc(self.x_label)
            .y_desc(self.y_label)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 15))
            .draw()?;
        let series = self.series();
        for (name, colour, marker) in &series {
            let pts: Vec<(f64, f64)> = self.points.iter().filter(|p| &p.series == name).map(|p| (p.x, p.y)).collect();
            chart.draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))?;
            for p in pts {
                chart.plotting_area().draw(&marker.at(p, *colour))?;
            }
        }
        for p in self.points.iter().filter(|p| p.reference) {
            chart.plotting_area().draw(&Circle::new((p.x, p.y), 9, BLACK.stroke_width(2)))?;
        }
        // The legend, below the data (and the x axis label).
        let mut y = LEGEND_ROW as i32 / 2;
        let x = 90;
        for (name, colour, marker) in &series {
            legend.draw(&PathElement::new(vec![(x, y), (x + 28, y)], colour.stroke_width(2)))?;
            legend.draw(&marker.at_pixel((x + 14, y), *colour))?;
            legend.draw(&Text::new(name.clone(), (x + 40, y - 8), (FONT, 14)))?;
            y += LEGEND_ROW as i32;
        }
        if let (Some(label), true) = (self.reference_label, self.points.iter().any(|p| p.reference)) {
            legend.draw(&Circle::new((x + 14, y), 9, BLACK.stroke_width(2)))?;
            legend.draw(&Text::new(label.to_string(), (x + 40, y - 8), (FONT, 14)))?;
        }
        root.present()?;
        Ok(())
    }

    /// The image size: the plot and one legend row per series (and the reference).
    fn size(&self) -> (u32, u32) {
        let rows = self.series().len()
            + usize::from(self.reference_label.is_some() && self.points.iter().any(|p| p.reference));
        (SIZE.0, SIZE.1 + LEGEND_ROW * rows as u32 + 8)
    }

    /// (series, colour, marker) in order of first appearance: the colour by case (the name
    /// before its last comma), the marker by mesh family (after it).
    fn series(&self) -> Vec<(String, RGBColor, Marker)> {
        let mut names: Vec<&str> = Vec::new();
        for p in &self.points {
            if !names.contains(&p.series.as_str()) {
                names.push(&p.series);
            }
        }
        let split = |n: &str| {
            n.rsplit_once(',').map_or((n.to_string(), String::new()), |(a, b)| (a.to_string(), b.trim().to_string()))
        };
        let mut cases: Vec<String> = Vec::new();
        let mut families: Vec<String> = Vec::new();
        names
            .iter()
            .map(|n| {
                let (case, family) = split(n);
                let ci = cases.iter().position(|c| *c == case).unwrap_or_else(|| {
                    cases.push(case);
                    cases.len() - 1
                });
                let fi = families.iter().position(|f| *f == family).unwrap_or_else(|| {
                    families.push(family);
                    families.len() - 1
                });
                (n.to_string(), COLOURS[ci % COLOURS.len()], Marker::ALL[fi % Marker::ALL.len()])
            })
            .collect()
    }
}

/// Colour-blind-safe colours (Okabe and Ito).
const COLOURS: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

#[derive(Clone, Copy, Debug, PartialEq)]
enum Marker {
    Circle,
    Triangle,
    Square,
    Diamond,
}

impl Marker {
    const ALL: [Marker; 4] = [Marker::Circle, Marker::Triangle, Marker::Square, Marker::Diamond];

    /// The marker at data point `p`.
    fn at<'a, DB: DrawingBackend + 'a>(self, p: (f64, f64), colour: RGBColor) -> DynElement<'a, DB, (f64, f64)> {
        self.placed(p, colour)
    }

    /// The marker at pixel `p` (the legend).
    fn at_pixel<'a, DB: DrawingBackend + 'a>(self, p: (i32, i32), colour: RGBColor) -> DynElement<'a, DB, (i32, i32)> {
        self.placed(p, colour)
    }

    fn placed<'a, DB: DrawingBackend + 'a, C: Clone + 'a>(self, p: C, colour: RGBColor) -> DynElement<'a, DB, C> {
        let r = 5;
        let style = colour.filled();
        let at = EmptyElement::at(p);
        match self {
            Marker::Circle => (at + Circle::new((0, 0), r, style)).into_dyn(),
            Marker::Triangle => (at + Polygon::new(vec![(0, -r - 1), (r + 1, r), (-r - 1, r)], style)).into_dyn(),
            Marker::Square => (at + Rectangle::new([(-r + 1, -r + 1), (r - 1, r - 1)], style)).into_dyn(),
            Marker::Diamond => {
                (at + Polygon::new(vec![(0, -r - 1), (r + 1, 0), (0, r + 1), (-r - 1, 0)], style)).into_dyn()
            }
        }
    }
}

/// The 1, 2, 5 x 10^k inside [lo, hi]; only the decades over a wide range, every m x 10^k over
/// a narrow one (so that at least three are labelled).
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let all = decade_multiples(lo, hi, &[1.0, 2.0, 5.0]);
    if all.len() > 12 {
        decade_multiples(lo, hi, &[1.0])
    } else if all.len() < 3 {
        minor_ticks(lo, hi)
    } else {
        all
    }
}

/// The m x 10^k (m = 1..9) inside [lo, hi]: the light grid.
fn minor_ticks(lo: f64, hi: f64) -> Vec<f64> {
    decade_multiples(lo, hi, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
}

fn decade_multiples(lo: f64, hi: f64, multiples: &[f64]) -> Vec<f64> {
    let mut v = Vec::new();
    for k in lo.log10().floor() as i32..=hi.log10().ceil() as i32 {
        for m in multiples {
            let x = m * 10f64.powi(k);
            if x >= lo && x <= hi {
                v.push(x);
            }
        }
    }
    v
}

/// A tick label: "0.02", "5", "100", "2e4" (no trailing zeros, no float noise).
fn tick_label(v: f64) -> String {
    if v <= 0.0 || !v.is_finite() {
        return String::new();
    }
    let k = v.log10().floor() as i32;
    let mantissa = v / 10f64.powi(k);
    if k >= 5 {
        format!("{}e{k}", mantissa.round())
    } else if k >= 0 {
        format!("{}", v.round())
    } else if k >= -3 {
        format!("{:.*}", (-k) as usize, v)
    } else {
        format!("{}e{k}", mantissa.round())
    }
}

/// Text is laid out (both backends) and drawn (bitmap) with a registered TrueType font: the first found of the usual
/// system sans-serif fonts (or `SKINSIM_FONT`).
fn register_font() -> Result<(), Box<dyn std::error::Error>> {
    static DONE: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    let result = DONE.get_or_init(|| {
        let candidates = std::env::var("SKINSIM_FONT").into_iter().chain(
            [
                "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
                "/usr/share/fonts/TTF/DejaVuSans.ttf",
                "/usr/share/fonts/dejavu/DejaVuSans.ttf",
                "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
                "/usr/share/fonts/liberation/LiberationSans-Regular.ttf",
                "/Library/Fonts/Arial.ttf",
                "C:\\Windows\\Fonts\\arial.ttf",
            ]
            .map(String::from),
        );
        for path in candidates {
            if let Ok(bytes) = std::fs::read(&path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font(FONT, FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err("no TrueType font for the PNG plots: install fonts-dejavu-core, or set SKINSIM_FONT to a .ttf file".into())
    });
    result.clone().map_err(Into::into)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_are_1_2_5_and_read_cleanly() {
        assert_eq!(ticks(0.15, 30.0), vec![0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0]);
        let labels: Vec<String> = [0.3, 0.02, 1.0, 5.0, 100.0, 10000.0, 2e5, 2e-5].map(tick_label).to_vec();
        assert_eq!(labels, ["0.3", "0.02", "1", "5", "100", "10000", "2e5", "2e-5"]);
        assert_eq!(minor_ticks(1.0, 10.0).len(), 10);
        assert_eq!(ticks(35.0, 140.0), vec![40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0]);
    }

    #[test]
    fn colour_follows_the_case_and_marker_the_mesh_family() {
        let p = |s: &str| Point { series: s.into(), x: 1.0, y: 1.0, reference: false };
        let plot = LogLog {
            caption: "",
            x_label: "",
            y_label: "",
            points: vec![
                p("case 10 (strip, 6 mm), uniform"),
                p("case 10 (strip, 6 mm), adaptive"),
                p("case 11, uniform"),
            ],
            reference_label: None,
        };
        let s = plot.series();
        assert_eq!(s[0].1, s[1].1);
        assert_ne!(s[0].1, s[2].1);
        assert_eq!(s[0].2, s[2].2);
        assert_ne!(s[0].2, s[1].2);
    }
}
