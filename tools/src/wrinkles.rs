//! Wrinkle analysis (VALIDATION.md C): from a layer's surface, the height profile along the
//! compression axis, the dominant wavelengths (spectral peaks), the amplitude, the compression,
//! and the strain at which wrinkles first appear (from amplitude against strain).

use glam::{DVec2, DVec3};
use rustfft::num_complex::Complex;
use rustfft::FftPlanner;

/// Heights along the material coordinate `s` of the compression axis (sorted, detrended).
#[derive(Clone, Debug, Default)]
pub struct Profile {
    pub s: Vec<f64>,
    pub h: Vec<f64>,
}

/// A spectral peak.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    /// In material length (m).
    pub wavelength: f64,
    /// Relative magnitude (the largest peak is 1).
    pub strength: f64,
}

/// The height profile of a surface along `axis` (0 = x, 1 = y) of material space: vertices with
/// the same material coordinate along the axis are averaged (rows of a strip), the height is
/// the z coordinate, and the mean is removed.
pub fn profile(positions: &[DVec3], material: &[DVec2], axis: usize) -> Profile {
    let mut pts: Vec<(f64, f64)> = positions.iter().zip(material).map(|(p, m)| (m[axis], p.z)).collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let span = pts.last().map_or(0.0, |l| l.0) - pts.first().map_or(0.0, |f| f.0);
    let tol = 1e-9 * span.max(1e-300);
    let mut out = Profile::default();
    let mut i = 0;
    while i < pts.len() {
        let (mut sum, mut n, s0) = (0.0, 0.0, pts[i].0);
        while i < pts.len() && pts[i].0 - s0 <= tol {
            sum += pts[i].1;
            n += 1.0;
            i += 1;
        }
        out.s.push(s0);
        out.h.push(sum / n);
    }
    let mean = out.h.iter().sum::<f64>() / out.h.len().max(1) as f64;
    out.h.iter_mut().for_each(|h| *h -= mean);
    out
}

/// Half the peak-to-peak height.
pub fn amplitude(p: &Profile) -> f64 {
    let (lo, hi) = p.h.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), h| (a.min(*h), b.max(*h)));
    if p.h.is_empty() {
        0.0
    } else {
        0.5 * (hi - lo)
    }
}

/// Compression along `axis`: 1 - deformed extent / material extent.
pub fn compression(positions: &[DVec3], material: &[DVec2], axis: usize) -> f64 {
    let ext = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
        hi - lo
    };
    let deformed = ext(&mut positions.iter().map(|p| p[axis]));
    let rest = ext(&mut material.iter().map(|m| m[axis]));
    1.0 - deformed / rest
}

/// Spectral peaks of a profile, strongest first, down to `min_strength` of the strongest.
/// `periodic`: the profile's last sample repeats its first (a periodic domain): no window, and
/// wavelengths are exact fractions of the period. Otherwise a Hann window is applied.
/// Without periodicity, peak positions are refined by parabolic interpolation of the log
/// magnitude.
pub fn peaks(p: &Profile, periodic: bool, min_strength: f64) -> Vec<Peak> {
    match spectrum(p, periodic, None) {
        Some((mag, length)) => peaks_of(&mag, length, periodic, min_strength),
        None => Vec::new(),
    }
}

/// Spectral peaks of a 2D surface along `axis`: the power spectra of every line of vertices at
/// one material coordinate across the axis (rows of a grid), summed, so that wrinkles that are
/// not straight across the patch still count (averaging the heights first would cancel them).
/// Lines shorter than 8 vertices are skipped.
pub fn row_peaks(positions: &[DVec3], material: &[DVec2], axis: usize, min_strength: f64) -> Vec<Peak> {
    let across = 1 - axis;
    let mut rows: Vec<(f64, DVec3, DVec2)> = positions.iter().zip(material).map(|(p, m)| (m[across], *p, *m)).collect();
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let span = rows.last().map_or(0.0, |l| l.0) - rows.first().map_or(0.0, |f| f.0);
    let tol = 1e-9 * span.max(1e-300);
    let mut power: Vec<f64> = Vec::new();
    let (mut length, mut n_fft) = (0.0, None);
    let mut i = 0;
    while i < rows.len() {
        let start = i;
        while i < rows.len() && rows[i].0 - rows[start].0 <= tol {
            i += 1;
        }
        if i - start < 8 {
            continue;
        }
        let (pos, mat): (Vec<DVec3>, Vec<DVec2>) = rows[start..i].iter().map(|r| (r.1, r.2)).unzip();
        let line = profile(&pos, &mat, axis);
        let n = *n_fft.get_or_insert_with(|| (4 * line.s.len()).next_power_of_two());
        if let Some((mag, l)) = spectrum(&line, false, Some(n)) {
            length = l;
            power.resize(mag.len(), 0.0);
            power.iter_mut().zip(&mag).for_each(|(p, m)| *p += m * m);
        }
    }
    let mag: Vec<f64> = power.iter().map(|p| p.sqrt()).collect();
    if mag.len() < 4 {
        return Vec::new();
    }
    peaks_of(&mag, length, false, min_strength)
}

/// The magnitude spectrum of a profile resampled on `n` points (default 4x its samples, to a
/// power of two), and the length one period of the transform stands for.
fn spectrum(p: &Profile, periodic: bool, n: Option<usize>) -> Option<(Vec<f64>, f64)> {
    if p.s.len() < 4 {
        return None;
    }
    let (s0, s1) = (p.s[0], *p.s.last().unwrap());
    let n_src = if periodic { p.s.len() - 1 } else { p.s.len() };
    let n = n.unwrap_or((4 * n_src).next_power_of_two());
    let domain = s1 - s0;
    // Uniform resampling (linear interpolation) over [s0, s1) (periodic) or [s0, s1].
    let step = if periodic { domain / n as f64 } else { domain / (n - 1) as f64 };
    let mut j = 0;
    let mut buf: Vec<Complex<f64>> = (0..n)
        .map(|i| {
            let s = s0 + i as f64 * step;
            while j + 2 < p.s.len() && p.s[j + 1] < s {
                j += 1;
            }
            let (a, b) = (p.s[j], p.s[j + 1]);
            let t = ((s - a) / (b - a)).clamp(0.0, 1.0);
            let mut v = p.h[j] + t * (p.h[j + 1] - p.h[j]);
            if !periodic {
                v *= 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64).cos();
            }
            Complex::new(v, 0.0)
        })
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let mag: Vec<f64> = buf[..n / 2].iter().map(|c| c.norm()).collect();
    let length = if periodic { domain } else { step * n as f64 };
    Some((mag, length))
}

/// Local maxima of a magnitude spectrum (bin k: wavelength length / k), strongest first.
fn peaks_of(mag: &[f64], length: f64, periodic: bool, min_strength: f64) -> Vec<Peak> {
    let top = mag[1..].iter().fold(0.0f64, |m, v| m.max(*v));
    if top <= 0.0 {
        return Vec::new();
    }
    let mut out: Vec<Peak> = (2..mag.len() - 1)
        .chain(std::iter::once(1).filter(|_| mag[1] > mag[2]))
        .filter(|&k| {
            mag[k] >= mag[k - 1].max(if k + 1 < mag.len() { mag[k + 1] } else { 0.0 }) && mag[k] >= min_strength * top
        })
        .map(|k| {
            let (a, b, c) =
                (mag[k - 1].max(1e-300).ln(), mag[k].ln(), mag[(k + 1).min(mag.len() - 1)].max(1e-300).ln());
            let denom = a - 2.0 * b + c;
            // A periodic domain holds whole waves only: its bins are exact.
            let delta =
                if !periodic && denom.abs() > 0.0 && k > 1 { (0.5 * (a - c) / denom).clamp(-0.5, 0.5) } else { 0.0 };
            Peak { wavelength: length / (k as f64 + delta), strength: mag[k] / top }
        })
        .collect();
    out.sort_by(|a, b| b.strength.total_cmp(&a.strength));
    out
}

/// How alike two lines of a wrinkled surface are: the correlation of the heights (z, mean
/// removed) along `axis` of the lines of vertices nearest to fractions `a` and `b` of the width
/// across it (material coordinates). 1 for straight wrinkles across the patch; lower for a
/// pattern that differs from line to line (issue 25: a randomized stratum corneum breaks the
/// symmetry a uniform one keeps).
pub fn line_correlation(positions: &[DVec3], material: &[DVec2], axis: usize, a: f64, b: f64) -> f64 {
    let across = 1 - axis;
    let (lo, hi) =
        material.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), m| (l.min(m[across]), h.max(m[across])));
    let nearest = |f: f64| {
        let target = lo + f * (hi - lo);
        material
            .iter()
            .map(|m| m[across])
            .min_by(|x, y| (x - target).abs().total_cmp(&(y - target).abs()))
            .unwrap_or(lo)
    };
    let line = |f: f64| {
        let at = nearest(f);
        let mut l: Vec<(f64, f64)> = positions
            .iter()
            .zip(material)
            .filter(|(_, m)| (m[across] - at).abs() <= 1e-9 * (hi - lo).max(f64::MIN_POSITIVE))
            .map(|(p, m)| (m[axis], p.z))
            .collect();
        l.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mean = l.iter().map(|x| x.1).sum::<f64>() / l.len().max(1) as f64;
        l.into_iter().map(|x| x.1 - mean).collect::<Vec<f64>>()
    };
    let (u, v) = (line(a), line(b));
    let n = u.len().min(v.len());
    let dot = |p: &[f64], q: &[f64]| p[..n].iter().zip(&q[..n]).map(|(x, y)| x * y).sum::<f64>();
    dot(&u, &v) / (dot(&u, &u) * dot(&v, &v)).sqrt().max(f64::MIN_POSITIVE)
}

/// The strain at which wrinkles appear: a least-squares fit of A^2 = c (eps - eps_0) (the
/// supercritical branch, A = h sqrt(eps / eps_c - 1)) over the points whose amplitude exceeds
/// `min_amplitude`. None with fewer than two such points.
pub fn onset_strain(series: &[(f64, f64)], min_amplitude: f64) -> Option<f64> {
    let pts: Vec<(f64, f64)> = series.iter().filter(|(_, a)| *a > min_amplitude).map(|&(e, a)| (e, a * a)).collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (se, sa) = pts.iter().fold((0.0, 0.0), |(x, y), (e, a)| (x + e, y + a));
    let (me, ma) = (se / n, sa / n);
    let (sxy, sxx) =
        pts.iter().fold((0.0, 0.0), |(xy, xx), (e, a)| (xy + (e - me) * (a - ma), xx + (e - me) * (e - me)));
    if sxx <= 0.0 || sxy <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some(me - ma / slope)
}

/// A triangle surface interpolated (linearly, per face) at the nodes of a regular material
/// grid of `cells` over the mesh's material bounding box: grid rows for `row_peaks` from an
/// adaptive mesh. Nodes outside every face are skipped. Returns (material, positions).
pub fn resample_on_grid(
    material: &[DVec2],
    positions: &[DVec3],
    faces: &[[u32; 3]],
    cells: (usize, usize),
) -> (Vec<DVec2>, Vec<DVec3>) {
    let (lo, hi) = material
        .iter()
        .fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(a, b), p| (a.min(*p), b.max(*p)));
    let step = (hi - lo) / DVec2::new(cells.0 as f64, cells.1 as f64);
    // Faces by the grid cells their bounding boxes touch.
    let cell_of = |p: DVec2| {
        let c = ((p - lo) / step).floor();
        (c.x.clamp(0.0, cells.0 as f64 - 1.0) as usize, c.y.clamp(0.0, cells.1 as f64 - 1.0) as usize)
    };
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); cells.0 * cells.1];
    for (fi, f) in faces.iter().enumerate() {
        let u = f.map(|i| material[i as usize]);
        let (a, b) = (cell_of(u[0].min(u[1]).min(u[2])), cell_of(u[0].max(u[1]).max(u[2])));
        for j in a.1..=b.1 {
            for i in a.0..=b.0 {
                bins[j * cells.0 + i].push(fi as u32);
            }
        }
    }
    let (mut uv, mut x) = (Vec::new(), Vec::new());
    for j in 0..=cells.1 {
        for i in 0..=cells.0 {
            let p = lo + step * DVec2::new(i as f64, j as f64);
            let (ci, cj) = cell_of(p);
            let hit = bins[cj * cells.0 + ci].iter().find_map(|&fi| {
                let f = faces[fi as usize];
                let u = f.map(|k| material[k as usize]);
                let d = (u[1] - u[0]).perp_dot(u[2] - u[0]);
                let b1 = (p - u[0]).perp_dot(u[2] - u[0]) / d;
                let b2 = (u[1] - u[0]).perp_dot(p - u[0]) / d;
                let tol = -1e-9;
                (b1 >= tol && b2 >= tol && 1.0 - b1 - b2 >= tol).then(|| {
                    let q = f.map(|k| positions[k as usize]);
                    q[0] * (1.0 - b1 - b2) + q[1] * b1 + q[2] * b2
                })
            });
            if let Some(q) = hit {
                uv.push(p);
                x.push(q);
            }
        }
    }
    (uv, x)
}

/// The dominant wave of a height field over a patch (issue 62: the direction of forehead lines
/// on a curved, irregular mesh): `height` per vertex, resampled linearly on a regular material
/// grid of spacing `step` (nodes off the mesh count 0), mean removed, a Hann window in both
/// directions, and the strongest bin of the 2D power spectrum away from the mean.
#[derive(Clone, Debug)]
pub struct Wave {
    /// The dominant wavelength (m) and its wave vector's angle from the material u axis
    /// (radians, in [0, pi)).
    pub wavelength: f64,
    pub angle: f64,
    /// The radial spectrum: (wavelength, power summed over the bins at that |k|), one entry per
    /// whole bin radius, longest wavelength first.
    pub radial: Vec<(f64, f64)>,
}

pub fn dominant_wave(material: &[DVec2], height: &[f64], faces: &[[u32; 3]], step: f64) -> Option<Wave> {
    let (lo, hi) = material
        .iter()
        .fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(a, b), p| (a.min(*p), b.max(*p)));
    let cells = ((hi - lo) / step).ceil();
    if !(cells.x >= 4.0 && cells.y >= 4.0 && cells.x * cells.y < 1e8) {
        return None;
    }
    let (nx, ny) = (cells.x as usize, cells.y as usize);
    let lifted: Vec<DVec3> = height.iter().map(|h| DVec3::new(0.0, 0.0, *h)).collect();
    let (uv, x) = resample_on_grid(material, &lifted, faces, (nx, ny));
    let (n, m) = ((4 * (nx + 1)).next_power_of_two(), (4 * (ny + 1)).next_power_of_two());
    let mean = x.iter().map(|p| p.z).sum::<f64>() / x.len().max(1) as f64;
    let mut grid = vec![Complex::new(0.0, 0.0); n * m];
    let gstep = (hi - lo) / DVec2::new(nx as f64, ny as f64);
    let hann = |i: f64, count: usize| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i / count as f64).cos();
    for (u, p) in uv.iter().zip(&x) {
        let c = ((*u - lo) / gstep).round();
        let (i, j) = (c.x as usize, c.y as usize);
        grid[j * n + i] = Complex::new((p.z - mean) * hann(c.x, nx) * hann(c.y, ny), 0.0);
    }
    let mut planner = FftPlanner::new();
    let rows = planner.plan_fft_forward(n);
    grid.chunks_exact_mut(n).for_each(|r| rows.process(r));
    let cols = planner.plan_fft_forward(m);
    let mut col = vec![Complex::new(0.0, 0.0); m];
    for i in 0..n {
        (0..m).for_each(|j| col[j] = grid[j * n + i]);
        cols.process(&mut col);
        (0..m).for_each(|j| grid[j * n + i] = col[j]);
    }
    // Wave numbers (cycles per metre) of bin (i, j); the half plane ky >= 0 holds every wave once.
    let (lx, ly) = (gstep.x * n as f64, gstep.y * m as f64);
    let k_of = |i: usize, j: usize| {
        let fi = if i <= n / 2 { i as f64 } else { i as f64 - n as f64 };
        let fj = if j <= m / 2 { j as f64 } else { j as f64 - m as f64 };
        DVec2::new(fi / lx, fj / ly)
    };
    let dk = (1.0 / lx).max(1.0 / ly);
    let mut best = (0.0, DVec2::ZERO);
    let mut radial: Vec<f64> = Vec::new();
    for j in 0..=m / 2 {
        for i in 0..n {
            let k = k_of(i, j);
            let power = grid[j * n + i].norm_sqr();
            let bin = (k.length() / dk).round() as usize;
            if bin >= radial.len() {
                radial.resize(bin + 1, 0.0);
            }
            radial[bin] += power;
            // (the domain's first bins are its window, not a wave)
            if k.length() > 2.0 * dk && power > best.0 {
                best = (power, k);
            }
        }
    }
    if best.0 <= 0.0 {
        return None;
    }
    let angle = best.1.y.atan2(best.1.x).rem_euclid(std::f64::consts::PI);
    let radial = radial.iter().enumerate().skip(1).map(|(b, p)| (1.0 / (b as f64 * dk), *p)).collect();
    Some(Wave { wavelength: 1.0 / best.1.length(), angle, radial })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn synthetic(f: impl Fn(f64) -> f64, n: usize, len: f64) -> Profile {
        let s: Vec<f64> = (0..=n).map(|i| len * i as f64 / n as f64).collect();
        let h = s.iter().map(|&x| f(x)).collect();
        Profile { s, h }
    }

    #[test]
    fn an_unstructured_mesh_resampled_on_a_grid_keeps_its_wavelength() {
        // A wavy sheet on an irregular triangulation (jittered interior nodes).
        let (n, len, lambda) = (60usize, 0.06, 0.006);
        let mut uv = Vec::new();
        for j in 0..=n / 6 {
            for i in 0..=n {
                let jitter = |k: usize| {
                    if i == 0 || i == n || j == 0 || j == n / 6 {
                        0.0
                    } else {
                        ((k * 7919) % 17) as f64 / 17.0 - 0.5
                    }
                };
                let h = len / n as f64;
                uv.push(DVec2::new(
                    i as f64 * h + 0.3 * h * jitter(i + 31 * j),
                    j as f64 * h + 0.3 * h * jitter(3 * i + j),
                ));
            }
        }
        let row = n + 1;
        let mut faces = Vec::new();
        for j in 0..n / 6 {
            for i in 0..n {
                let v = (j * row + i) as u32;
                let w = v + row as u32;
                faces.push([v, v + 1, w + 1]);
                faces.push([v, w + 1, w]);
            }
        }
        let wave = |u: DVec2| DVec3::new(u.x, u.y, 1e-4 * (2.0 * std::f64::consts::PI * u.x / lambda).sin());
        let x: Vec<DVec3> = uv.iter().map(|&u| wave(u)).collect();
        let (guv, gx) = resample_on_grid(&uv, &x, &faces, (120, 5));
        assert_eq!(guv.len(), 121 * 6, "every node lies in a face");
        let worst = guv.iter().zip(&gx).map(|(u, p)| (p.z - wave(*u).z).abs()).fold(0.0f64, f64::max);
        // Linear interpolation at 6 elements per wavelength: A (k h)^2 / 8 = 0.14 A, plus the jitter.
        assert!(worst < 0.25e-4, "linear interpolation error {worst:e}");
        let peaks = row_peaks(&gx, &guv, 0, 0.05);
        assert!((peaks[0].wavelength / lambda - 1.0).abs() < 0.02, "{peaks:?}");
    }

    #[test]
    fn a_periodic_sine_has_one_exact_peak() {
        let len = 0.17426;
        let p = synthetic(|x| 1e-3 * (2.0 * std::f64::consts::PI * 4.0 * x / len).cos(), 80, len);
        let pk = peaks(&p, true, 0.2);
        assert_eq!(pk.len(), 1, "{pk:?}");
        assert!((pk[0].wavelength / (len / 4.0) - 1.0).abs() < 1e-9, "{pk:?}");
        assert!((amplitude(&p) - 1e-3).abs() < 1e-12);
    }

    #[test]
    fn two_superposed_wavelengths_give_two_peaks() {
        let len = 0.1;
        let p = synthetic(
            |x| {
                1e-3 * (2.0 * std::f64::consts::PI * x / 0.01).sin()
                    + 0.5e-3 * (2.0 * std::f64::consts::PI * x / 0.0025).sin()
            },
            400,
            len,
        );
        let pk = peaks(&p, false, 0.2);
        assert!(pk.len() >= 2, "{pk:?}");
        assert!((pk[0].wavelength / 0.01 - 1.0).abs() < 0.02, "{pk:?}");
        assert!((pk[1].wavelength / 0.0025 - 1.0).abs() < 0.02, "{pk:?}");
    }

    #[test]
    fn row_spectra_find_waves_that_row_averaging_cancels() {
        // Waves of wavelength 4 along x whose phase turns by half a wave every row: the mean
        // height at each x is zero, each row alone is a clean sine.
        let (mut pos, mut mat) = (Vec::new(), Vec::new());
        for row in 0..6 {
            for i in 0..=80 {
                let x = i as f64 * 0.5;
                let z = (2.0 * std::f64::consts::PI * x / 4.0 + std::f64::consts::PI * row as f64).sin();
                pos.push(DVec3::new(x, row as f64, z));
                mat.push(DVec2::new(x, row as f64));
            }
        }
        assert!(amplitude(&profile(&pos, &mat, 0)) < 1e-9, "averaged rows cancel");
        let pk = row_peaks(&pos, &mat, 0, 0.25);
        assert!((pk[0].wavelength - 4.0).abs() < 0.04, "{pk:?}");
    }

    #[test]
    fn onset_from_the_supercritical_branch() {
        let eps_c = 0.0052;
        let series: Vec<(f64, f64)> =
            (0..30).map(|i| 0.0006 * i as f64).map(|e| (e, 1e-3 * (e / eps_c - 1.0).max(0.0).sqrt())).collect();
        let onset = onset_strain(&series, 1e-5).unwrap();
        assert!((onset / eps_c - 1.0).abs() < 1e-9, "{onset}");
    }

    #[test]
    fn rows_are_averaged_and_compression_measured() {
        let material: Vec<DVec2> =
            (0..10).flat_map(|i| [DVec2::new(i as f64, 0.0), DVec2::new(i as f64, 1.0)]).collect();
        let positions: Vec<DVec3> =
            material.iter().map(|m| DVec3::new(0.9 * m.x, m.y, if m.y > 0.5 { 2.0 } else { 0.0 })).collect();
        let p = profile(&positions, &material, 0);
        assert_eq!(p.s.len(), 10);
        assert!(p.h.iter().all(|h| h.abs() < 1e-15), "averaged rows, mean removed");
        assert!((compression(&positions, &material, 0) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn the_dominant_wave_of_a_tilted_wave_has_its_wavelength_and_direction() {
        // A 6 mm wave whose crests run at 30 degrees to u (wave vector at 120 degrees), on a grid.
        let (lambda, angle) = (0.006, 120f64.to_radians());
        let n = 80;
        let uv: Vec<DVec2> =
            (0..=n).flat_map(|j| (0..=n).map(move |i| DVec2::new(i as f64, j as f64) * 0.0005)).collect();
        let mut faces = Vec::new();
        for j in 0..n as u32 {
            for i in 0..n as u32 {
                let v = j * (n + 1) as u32 + i;
                let w = v + (n + 1) as u32;
                faces.extend([[v, v + 1, w + 1], [v, w + 1, w]]);
            }
        }
        let k = DVec2::new(angle.cos(), angle.sin()) * (2.0 * std::f64::consts::PI / lambda);
        let h: Vec<f64> = uv.iter().map(|u| 1e-4 * k.dot(*u).sin()).collect();
        let w = dominant_wave(&uv, &h, &faces, 0.00025).unwrap();
        assert!((w.wavelength / lambda - 1.0).abs() < 0.05, "{}", w.wavelength);
        assert!((w.angle - angle).abs() < 3f64.to_radians(), "{}", w.angle.to_degrees());
    }
}
