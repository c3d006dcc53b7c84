//! Property maps (LK14 5.2): reads a PNG or rasterizes a procedural map into an `RgbMap` over the
//! layer's material rectangle, and checks that every colour maps to positive factors.

use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};

use super::built::LayerMesh;
use super::context::Builder;
use super::schema::{MapSource, PropertiesSpec};
use super::SceneError;
use crate::model::{ChannelMap, LayerProperties, RgbMap};

/// Raster size of procedural maps (smooth fields: bilinear sampling of this grid is exact for
/// ramps and within 1e-4 for the others).
const PROCEDURAL_SIZE: usize = 257;

impl Builder {
    pub(super) fn properties(
        &self,
        at: &str,
        p: &PropertiesSpec,
        mesh: &LayerMesh,
    ) -> Result<LayerProperties, SceneError> {
        let uv = mesh.material_positions();
        let (lo, hi) = crate::mesh::bounds(&uv);
        let map = self.rgb_map(&format!("{at}.map"), &p.map, lo, hi)?;
        let channel = |name: &str, k: usize, m: Option<(f64, f64)>| -> Result<Option<ChannelMap>, SceneError> {
            let Some((a, b)) = m else { return Ok(None) };
            let cm = ChannelMap { lo: a, hi: b };
            let (cmin, cmax) = map
                .values
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(x, y), v| (x.min(v[k] as f64), y.max(v[k] as f64)));
            for c in [cmin, cmax] {
                let f = cm.factor(c);
                if !(f > 0.0 && f.is_finite()) {
                    let colour = ["red", "green", "blue"][k];
                    return Err(self.err(
                        format!("{at}.{name}"),
                        format!("maps {colour} {c:.3} (present in the map) to a {name} factor of {f}: must be > 0"),
                    ));
                }
            }
            Ok(Some(cm))
        };
        Ok(LayerProperties {
            wavelength: channel("wavelength", 0, p.wavelength)?,
            young: channel("young", 1, p.young)?,
            thickness: channel("thickness", 2, p.thickness)?,
            map,
        })
    }

    /// A PNG or procedural map stretched over [lo, hi] of material space.
    pub(super) fn rgb_map(&self, field: &str, source: &MapSource, lo: DVec2, hi: DVec2) -> Result<RgbMap, SceneError> {
        match source {
            MapSource::Png(path) => self.png_map(field, path, lo, hi),
            source => {
                self.check_colours(field, source)?;
                Ok(rasterize(source, lo, hi))
            }
        }
    }

    fn png_map(&self, field: &str, path: &str, lo: DVec2, hi: DVec2) -> Result<RgbMap, SceneError> {
        let full = self.dir.join(path);
        if let Some(problem) = super::context::not_a_file(&full) {
            return Err(SceneError::at_field(&full, field, format!("cannot read the map image: {problem}")));
        }
        let img = image::open(&full)
            .map_err(|e| SceneError::at_field(&full, field, format!("cannot read the map image: {e}")))?;
        if !img.color().has_color() {
            return Err(SceneError::at_field(
                &full,
                field,
                format!("a property map must be RGB (this image is {:?})", img.color()),
            ));
        }
        let rgb = img.to_rgb32f();
        let (width, height) = (rgb.width() as usize, rgb.height() as usize);
        if width == 0 || height == 0 {
            return Err(SceneError::at_field(&full, field, format!("the map is empty ({width} x {height} pixels)")));
        }
        Ok(RgbMap { width, height, values: rgb.pixels().map(|p| p.0).collect(), lo, hi })
    }

    fn check_colours(&self, field: &str, source: &MapSource) -> Result<(), SceneError> {
        let colours: Vec<(f64, f64, f64)> = match source {
            MapSource::Png(_) => vec![],
            MapSource::Constant(c) => vec![*c],
            MapSource::Ramp { from, to, .. } => vec![*from, *to],
            MapSource::Radial { inner, outer } => vec![*inner, *outer],
            MapSource::Noise { low, high, cells, .. } => {
                if *cells == 0 || *cells > 256 {
                    return Err(self.err(format!("{field}.cells"), format!("must be in 1..=256 (got {cells})")));
                }
                vec![*low, *high]
            }
        };
        for c in colours {
            if ![c.0, c.1, c.2].iter().all(|v| (0.0..=1.0).contains(v)) {
                return Err(self.err(field, format!("colour {c:?}: every channel must be in [0, 1]")));
            }
        }
        Ok(())
    }
}

/// A procedural map as a raster over [lo, hi] (row 0 at max y, as images are).
fn rasterize(source: &MapSource, lo: DVec2, hi: DVec2) -> RgbMap {
    let n = PROCEDURAL_SIZE;
    let v = |c: (f64, f64, f64)| DVec3::new(c.0, c.1, c.2);
    let lattice: Vec<f64> = match source {
        MapSource::Noise { seed, cells, .. } => {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(*seed);
            (0..(cells + 1) * (cells + 1)).map(|_| rng.random_range(0.0..=1.0)).collect()
        }
        _ => Vec::new(),
    };
    let colour = |t: DVec2| -> DVec3 {
        match source {
            MapSource::Png(_) => unreachable!("PNG maps are read, not rasterized"),
            MapSource::Constant(c) => v(*c),
            MapSource::Ramp { axis, from, to } => {
                let s = if axis.index() == 1 { t.y } else { t.x };
                v(*from).lerp(v(*to), s)
            }
            MapSource::Radial { inner, outer } => {
                let size = hi - lo;
                let d = ((t - DVec2::splat(0.5)) * size).length() / (0.5 * size.min_element().max(f64::MIN_POSITIVE));
                v(*inner).lerp(v(*outer), d.min(1.0))
            }
            MapSource::Noise { cells, low, high, .. } => {
                let c = *cells as usize;
                let g = t * c as f64;
                let (i, j) = ((g.x.floor() as usize).min(c - 1), (g.y.floor() as usize).min(c - 1));
                let smooth = |a: f64| a * a * (3.0 - 2.0 * a);
                let (ax, ay) = (smooth(g.x - i as f64), smooth(g.y - j as f64));
                let at = |i: usize, j: usize| lattice[j * (c + 1) + i];
                let r = (at(i, j) * (1.0 - ax) + at(i + 1, j) * ax) * (1.0 - ay)
                    + (at(i, j + 1) * (1.0 - ax) + at(i + 1, j + 1) * ax) * ay;
                v(*low).lerp(v(*high), r)
            }
        }
    };
    let mut values = Vec::with_capacity(n * n);
    for row in 0..n {
        for col in 0..n {
            let t = DVec2::new(col as f64, (n - 1 - row) as f64) / (n - 1) as f64;
            values.push(colour(t).as_vec3().to_array());
        }
    }
    RgbMap { width: n, height: n, values, lo, hi }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::schema::Axis;

    #[test]
    fn ramps_and_radial_maps_sample_as_declared() {
        let (lo, hi) = (DVec2::ZERO, DVec2::new(2.0, 1.0));
        let ramp = rasterize(&MapSource::Ramp { axis: Axis::X, from: (0.0, 0.0, 0.0), to: (1.0, 0.5, 0.0) }, lo, hi);
        let c = ramp.sample(DVec2::new(0.5, 0.3));
        assert!((c - DVec3::new(0.25, 0.125, 0.0)).length() < 1e-6, "{c}");
        let radial = rasterize(&MapSource::Radial { inner: (1.0, 1.0, 1.0), outer: (0.0, 0.0, 0.0) }, lo, hi);
        assert!((radial.sample(DVec2::new(1.0, 0.5)).x - 1.0).abs() < 1e-6);
        assert!(radial.sample(DVec2::new(1.0, 0.0)).x.abs() < 1e-6, "half the smaller side is the rim");
    }

    #[test]
    fn noise_is_seeded_and_within_its_colours() {
        let src = |seed| MapSource::Noise { seed, cells: 4, low: (0.2, 0.2, 0.2), high: (0.8, 0.8, 0.8) };
        let (lo, hi) = (DVec2::ZERO, DVec2::ONE);
        let (a, b, c) = (rasterize(&src(1), lo, hi), rasterize(&src(1), lo, hi), rasterize(&src(2), lo, hi));
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.values.iter().all(|v| v.iter().all(|x| (0.2 - 1e-6..=0.8 + 1e-6).contains(&(*x as f64)))));
    }
}
