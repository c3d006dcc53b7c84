//! A smooth geometric imperfection: a normal offset of amplitude x Perlin noise over material
//! space (the `cell` form of a scene's perturbation), plus any sinusoids (`waves`). It depends
//! on the material point only, so every mesh of a layer, and every vertex a remesh creates,
//! carries the same imperfection.

use glam::{DMat2, DVec2, DVec3};
use noise::NoiseFn;

use super::remesh::{remesh_sized, FaceRules, RemeshParams, RemeshVertex, Remeshed};
use super::shading::vertex_normals;

#[derive(Clone, Debug)]
pub struct Imperfection {
    /// Largest offset of the noise (m).
    pub amplitude: f64,
    /// Perlin cell (m).
    pub cell: f64,
    pub waves: Vec<Wave>,
    perlin: noise::Perlin,
}

/// amplitude x sin(2 pi u / wavelength), u the material coordinate `axis` (0: x, 1: y); m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wave {
    pub wavelength: f64,
    pub amplitude: f64,
    pub axis: usize,
}

impl Imperfection {
    pub fn new(amplitude: f64, cell: f64, seed: u64) -> Self {
        Self { amplitude, cell, waves: Vec::new(), perlin: noise::Perlin::new((seed ^ (seed >> 32)) as u32) }
    }

    pub(crate) fn with_waves(mut self, waves: Vec<Wave>) -> Self {
        self.waves = waves;
        self
    }

    /// The offset along the normal at a material point: the noise, in [-amplitude, amplitude],
    /// plus the waves.
    pub fn at(&self, uv: DVec2) -> f64 {
        let noise = self.amplitude * self.perlin.get((uv / self.cell).to_array()).clamp(-1.0, 1.0);
        let wave = |w: &Wave| w.amplitude * (std::f64::consts::TAU * uv[w.axis] / w.wavelength).sin();
        noise + self.waves.iter().map(wave).sum::<f64>()
    }

    /// Adds (`sign` 1) or removes (-1) the offsets of the vertices `which` selects, along the
    /// surface's vertex normals, leaving prescribed coordinates alone. (Removal uses the
    /// perturbed surface's normals, so it undoes an addition to first order in the amplitude.)
    pub fn apply(
        &self,
        sign: f64,
        rest: &mut [DVec3],
        uv: &[DVec2],
        faces: &[[u32; 3]],
        fixed: &[[bool; 3]],
        which: impl Fn(usize) -> bool,
    ) {
        let normals = vertex_normals(rest, faces);
        for (i, n) in normals.into_iter().enumerate().filter(|(i, _)| which(*i)) {
            let d = n * (sign * self.at(uv[i]));
            for k in (0..3).filter(|&k| !fixed[i][k]) {
                rest[i][k] += d[k];
            }
        }
    }
}

/// Remeshes the layer's rest shape without its smooth imperfection (if any), which new vertices
/// then get at their own material point: interpolating it from the parents would resample the
/// imperfection on the old mesh. (Survivors keep their rest positions.) A layer at rest (every
/// position its rest position, no velocity, bit for bit: the remesh before the first solve)
/// stays at rest: a new vertex takes its rest position, not the curved midpoint of its parents',
/// so the state is the one a uniform mesh of the same faces starts from (`Remeshed::at_rest`).
pub fn remesh_under(
    imperfection: Option<&Imperfection>,
    input: Vec<RemeshVertex>,
    faces: &[[u32; 3]],
    extra: &[DMat2],
    rules: &FaceRules,
    p: &RemeshParams,
) -> Remeshed {
    let at_rest = input.iter().all(|v| v.x == v.rest && v.v == DVec3::ZERO);
    let mut out = remesh_rest(imperfection, input, faces, extra, rules, p);
    if at_rest {
        out.vertices.iter_mut().filter(|v| v.origin.is_none()).for_each(|v| v.x = v.rest);
        out.at_rest = true;
    }
    out
}

fn remesh_rest(
    imperfection: Option<&Imperfection>,
    mut input: Vec<RemeshVertex>,
    faces: &[[u32; 3]],
    extra: &[DMat2],
    rules: &FaceRules,
    p: &RemeshParams,
) -> Remeshed {
    let Some(imp) = imperfection else { return remesh_sized(&input, faces, extra, rules, p) };
    let split = |v: &[RemeshVertex]| -> (Vec<DVec3>, Vec<DVec2>, Vec<[bool; 3]>) {
        (v.iter().map(|v| v.rest).collect(), v.iter().map(|v| v.uv).collect(), v.iter().map(|v| v.fixed).collect())
    };
    let (original, uv, fixed) = split(&input);
    let mut rest = original.clone();
    imp.apply(-1.0, &mut rest, &uv, faces, &fixed, |_| true);
    input.iter_mut().zip(rest).for_each(|(v, r)| v.rest = r);
    let mut out = remesh_sized(&input, faces, extra, rules, p);
    let (mut rest, uv, fixed) = split(&out.vertices);
    imp.apply(1.0, &mut rest, &uv, &out.faces, &fixed, |i| out.vertices[i].origin.is_none());
    for (v, r) in out.vertices.iter_mut().zip(rest) {
        v.rest = v.origin.map_or(r, |i| original[i as usize]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_are_bounded_smooth_and_removable() {
        let imp = Imperfection::new(1e-3, 0.5, 7);
        let samples: Vec<f64> = (0..400).map(|i| imp.at(DVec2::new(0.013 * i as f64, 0.29))).collect();
        assert!(samples.iter().all(|s| s.abs() <= 1e-3) && samples.iter().any(|s| s.abs() > 2e-4));
        // Smooth: neighbouring samples 0.013 apart (a fortieth of a cell) differ little.
        assert!(samples.windows(2).all(|w| (w[1] - w[0]).abs() < 2e-4));
        // A flat sheet: add then remove gives the sheet back (to second order); fixed coordinates
        // stay.
        let uv = [DVec2::ZERO, DVec2::new(1.0, 0.1), DVec2::new(0.2, 1.3)];
        let flat: Vec<DVec3> = uv.iter().map(|u| u.extend(0.0)).collect();
        let fixed = [[false; 3], [false; 3], [false, false, true]];
        let mut rest = flat.clone();
        imp.apply(1.0, &mut rest, &uv, &[[0, 1, 2]], &fixed, |_| true);
        assert_eq!(rest[2], flat[2]);
        assert!((rest[1].z - imp.at(uv[1])).abs() < 1e-15);
        imp.apply(-1.0, &mut rest, &uv, &[[0, 1, 2]], &fixed, |_| true);
        // (removal uses the perturbed surface's normals: exact to first order in the amplitude)
        let error = rest.iter().zip(&flat).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
        assert!(error < 1e-3 * 1e-3, "{error}"); // amplitude^2 over a unit triangle (measured 1.1e-7)
    }

    #[test]
    fn waves_add_sinusoids_along_their_axis() {
        let noise = Imperfection::new(1e-4, 0.5, 7);
        let waves = vec![
            Wave { wavelength: 0.8, amplitude: 1e-3, axis: 0 },
            Wave { wavelength: 0.2, amplitude: 5e-4, axis: 1 },
        ];
        let imp = noise.clone().with_waves(waves);
        for uv in [DVec2::new(0.2, 0.05), DVec2::new(0.37, 0.9), DVec2::new(1.1, 0.0)] {
            let expected = noise.at(uv)
                + 1e-3 * (std::f64::consts::TAU * uv.x / 0.8).sin()
                + 5e-4 * (std::f64::consts::TAU * uv.y / 0.2).sin();
            assert!((imp.at(uv) - expected).abs() < 1e-18, "{uv}");
        }
        // A crest of the first wave a quarter wavelength from the origin, and its node at half.
        let at = |x: f64| imp.at(DVec2::new(x, 0.0)) - noise.at(DVec2::new(x, 0.0));
        assert!((at(0.2) - 1e-3).abs() < 1e-15 && at(0.4).abs() < 1e-15);
    }
}
