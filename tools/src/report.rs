//! `skinsim report`: speed against error (VALIDATION.md F) for the wrinkling cases, as a
//! markdown table, a CSV and a log-log plot as SVG and PNG (time per increment against error).

use std::fmt::Write as _;
use std::path::Path;

use crate::film::FilmSubstrate;
use crate::plot::{LogLog, Point};
use crate::skin_section::{SkinSection, PREDICTED_AMPLITUDE_UM, PREDICTED_ONSET, PREDICTED_WAVELENGTH_MM};

/// One run of a sweep.
#[derive(Clone, Debug)]
pub struct Row {
    pub series: &'static str,
    pub resolution: String,
    pub vertices: usize,
    pub ms_per_increment: f64,
    pub newton_iterations: u32,
    pub wavelength_error: f64,
    pub onset_error: f64,
    pub amplitude_error: f64,
}

impl Row {
    /// The error the plot shows: the worst of the onset and amplitude errors.
    pub fn error(&self) -> f64 {
        self.onset_error.abs().max(self.amplitude_error.abs())
    }
}

/// Runs the sweeps; `quick` keeps the two coarsest resolutions of each.
pub fn speed_error(out: &Path, quick: bool) -> Result<Vec<Row>, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out)?;
    let mut rows = Vec::new();
    let take = |v: &[u32]| if quick { v[..2].to_vec() } else { v.to_vec() };
    for (series, grading) in [("case 7, graded substrate", 20.0), ("case 7, uniform substrate", 1.0)] {
        for cpw in take(&[8, 10, 12, 16, 20, 24]) {
            let mut setup = FilmSubstrate::deep(1000.0, 8, cpw, cpw);
            setup.grading = grading;
            let r = setup.run()?;
            eprintln!("{series}, {cpw} per wavelength: {:.0} ms per increment", 1e3 * r.wall_per_increment_s);
            rows.push(Row {
                series,
                resolution: format!("{cpw} film elements / wavelength, {cpw} through the depth"),
                vertices: r.vertices,
                ms_per_increment: 1e3 * r.wall_per_increment_s,
                newton_iterations: r.newton_iterations,
                wavelength_error: r.wavelength_error(),
                onset_error: r.onset_error(),
                amplitude_error: r.worst_amplitude_error(),
            });
        }
    }
    for cpw in take(&[8, 10, 16, 20]) {
        let r = SkinSection { cells_per_wave: cpw, dermis_elements: cpw, hypodermis_elements: 4 }.run()?;
        eprintln!("case 9, {cpw} per wavelength: {:.0} ms per increment", 1e3 * r.wall_per_increment_s);
        let amplitude_error = r
            .at
            .iter()
            .zip(PREDICTED_AMPLITUDE_UM)
            .map(|((_, a, _), (_, p))| a / p - 1.0)
            .fold(0.0f64, |m, e| if e.abs() > m.abs() { e } else { m });
        rows.push(Row {
            series: "case 9, H15 parameters",
            resolution: format!("{cpw} SC elements / wavelength, {cpw} + 4 through dermis + hypodermis"),
            vertices: r.vertices,
            ms_per_increment: 1e3 * r.wall_per_increment_s,
            newton_iterations: r.newton_iterations,
            wavelength_error: r.first_wavelength_mm / PREDICTED_WAVELENGTH_MM - 1.0,
            onset_error: r.onset / PREDICTED_ONSET - 1.0,
            amplitude_error,
        });
    }
    write_table(out, &rows)?;
    plot(&out.join("speed_error"), &rows)?;
    Ok(rows)
}

fn write_table(out: &Path, rows: &[Row]) -> std::io::Result<()> {
    let mut md = String::from(
        "# Speed against error (VALIDATION.md F)\n\n\
         Regenerate: `cargo run --release --bin skinsim -- report --out report`.\n\
         Case 7: Ebar_f / Ebar_s = 1000, theory of Chen and Hutchinson; case 9: H15's 3D parameters in plane strain \
         against the layered-elasticity prediction (0.98 mm, 0.52 %, 66 / 96 / 138 um). Periodic domains of eight \
         wavelengths: the wavelength is a mode selection (neighbours 11-14 % away). Amplitude: worst of 1.5, 2, 3 eps_c \
         (case 7) or 5, 10, 20 % (case 9). Time: wall per quasistatic increment on this machine.\n\n\
         | series | resolution | vertices | ms / increment | Newton iterations | wavelength error | onset error | amplitude error |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let mut csv = String::from(
        "series,resolution,vertices,ms_per_increment,newton_iterations,wavelength_error,onset_error,amplitude_error\n",
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.0} | {} | {:+.2} % | {:+.2} % | {:+.2} % |",
            r.series,
            r.resolution,
            r.vertices,
            r.ms_per_increment,
            r.newton_iterations,
            100.0 * r.wavelength_error,
            100.0 * r.onset_error,
            100.0 * r.amplitude_error
        );
        let _ = writeln!(
            csv,
            "{},{},{},{:.3},{},{:.6},{:.6},{:.6}",
            csv_text(r.series),
            csv_text(&r.resolution),
            r.vertices,
            r.ms_per_increment,
            r.newton_iterations,
            r.wavelength_error,
            r.onset_error,
            r.amplitude_error
        );
    }
    std::fs::write(out.join("speed_error.md"), md)?;
    std::fs::write(out.join("speed_error.csv"), csv)
}

/// A text field of a CSV row: quoted, inner quotes doubled (RFC 4180), so that the commas in a
/// series' name or a setting stay inside their column.
pub fn csv_text(text: &str) -> String {
    format!("\"{}\"", text.replace('"', "\"\""))
}

fn plot(stem: &Path, rows: &[Row]) -> Result<(), Box<dyn std::error::Error>> {
    let points = rows
        .iter()
        .map(|r| Point {
            series: r.series.to_string(),
            x: 100.0 * r.error().max(1e-4),
            y: r.ms_per_increment,
            reference: false,
        })
        .collect();
    let plot = LogLog {
        caption: "H15 cases 7 and 9: time per increment against error",
        x_label: "worst of onset and amplitude error against theory (%)",
        y_label: "time per increment (ms)",
        points,
        reference_label: None,
    };
    plot.write(stem)
}
