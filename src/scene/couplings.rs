//! Building a patch's LK14 couplings: the critical wavelength from the scene's rule, checked
//! against the patch and its meshes, and the kernels clustered at load (LK14 4.1).

use glam::DVec2;

use super::built::{BuiltCoupling, LayerMesh};
use super::context::Builder;
use super::context::PatchContext;
use super::schema::*;
use super::SceneError;
use crate::coupling::kernels;
use crate::mesh;
use crate::model::LayerKind;

impl Builder {
    /// Validates a coupling and clusters its kernels (LK14 4.1) on a fine grid of the upper
    /// layer's material rectangle, 10 grid cells per smallest wavelength.
    pub(super) fn coupling(&self, at: &str, c: &CouplingSpec, cx: &PatchContext) -> Result<BuiltCoupling, SceneError> {
        let PatchContext { layers, len, stress, .. } = *cx;
        let find = |field: &str, name: &str| cx.find(self, format!("{at}.{field}"), name);
        let (ui, li) = (find("upper", &c.upper)?, find("lower", &c.lower)?);
        let (upper, lower) = (&layers[ui], &layers[li]);
        if upper.kind != LayerKind::Shell {
            return Err(self.err(format!("{at}.upper"), format!("\"{}\" is not a shell layer", upper.name)));
        }
        if ui == li {
            return Err(self.err(format!("{at}.lower"), "a layer cannot be coupled to itself"));
        }
        let LayerMesh::Surface(lower_mesh) = &lower.mesh else {
            return Err(
                self.err(format!("{at}.lower"), format!("\"{}\" is a volume: kernels need a surface", lower.name))
            );
        };
        let LayerMesh::Surface(upper_mesh) = &upper.mesh else { unreachable!("shells are surfaces") };
        let positive = |field: &str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(v)
            } else {
                Err(self.err(format!("{at}.wavelength.{field}"), format!("must be > 0 (got {v})")))
            }
        };
        let upper_e = upper.material.map_or(0.0, |m| m.young);
        let upper_h = upper.thickness.unwrap_or(0.0);
        let lambda = match &c.wavelength {
            WavelengthSpec::Constant(l) => positive("0", *l)? * len,
            WavelengthSpec::Eq31 { constant, lower: given } => {
                let (e, h) = match (given, lower.material, lower.thickness) {
                    (Some((e, h)), ..) => (positive("lower.0", *e)? * stress, positive("lower.1", *h)? * len),
                    (None, Some(m), Some(h)) => (m.young, h),
                    _ => {
                        return Err(self.err(
                            format!("{at}.wavelength.lower"),
                            format!("\"{}\" has no shell material: state (young, thickness)", lower.name),
                        ))
                    }
                };
                kernels::wavelength_two_layer(positive("constant", *constant)?, upper_h, h, upper_e, e)
            }
            WavelengthSpec::Film { substrate: (e, nu) } => {
                let e = positive("substrate.0", *e)? * stress;
                if !(*nu > -1.0 && *nu < 0.5) {
                    return Err(
                        self.err(format!("{at}.wavelength.substrate.1"), format!("must be in (-1, 0.5) (got {nu})"))
                    );
                }
                let nu_f = upper.material.map_or(0.0, |m| m.poisson);
                kernels::wavelength_film(upper_h, upper_e / (1.0 - nu_f * nu_f), e / (1.0 - nu * nu))
            }
        };
        // The upper layer's property map: red scales the wavelength; green and blue scale it
        // through the formula's powers of E and h (eq. 3.1: E^1/6 h^1/2; film: E^1/3 h).
        let (e_power, h_power) = match &c.wavelength {
            WavelengthSpec::Constant(_) => (0.0, 0.0),
            WavelengthSpec::Eq31 { .. } => kernels::TWO_LAYER_EXPONENTS,
            WavelengthSpec::Film { .. } => kernels::FILM_EXPONENTS,
        };
        let local = |uv: DVec2| {
            let f = crate::model::factors_at(upper.properties.as_ref(), uv);
            lambda * f.wavelength * f.young.powf(e_power) * f.thickness.powf(h_power)
        };
        let (lo, hi) = mesh::bounds(&upper_mesh.uv);
        let (lambda_min, lambda_max) = upper_mesh
            .uv
            .iter()
            .map(|u| local(*u))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), l| (a.min(l), b.max(l)));
        // Refused: a wavelength the patch cannot hold, or supports too small to hold a vertex.
        let extent = (hi - lo).max_element();
        if lambda_max > extent {
            return Err(self.err(
                format!("{at}.wavelength"),
                format!("the wavelength {:.4} m is larger than the patch ({:.4} m)", lambda_max, extent),
            ));
        }
        for (name, m) in [(&upper.name, upper_mesh), (&lower.name, lower_mesh)] {
            let spacing = m.mean_material_edge();
            if 0.5 * lambda_min < spacing {
                return Err(self.err(
                    format!("{at}.wavelength"),
                    format!(
                        "the kernel radius (half the wavelength, {:.3e} m) is below the mesh spacing of \"{name}\" \
                         ({spacing:.3e} m): refine the mesh or raise the wavelength",
                        0.5 * lambda_min
                    ),
                ));
            }
        }
        let layout = kernels::KERNEL_SCALE;
        if c.distance == kernels::KernelDistance::Geodesic {
            // Clustered on the upper layer's own rest surface (`coupling::geodesic`).
            let m = upper_mesh;
            let wavelength: Vec<f64> = m.uv.iter().map(|u| layout * local(*u)).collect();
            let space = crate::coupling::geodesic::SurfaceSpace::new(&m.rest, &m.uv, &m.faces);
            let kernels = space.build_kernels(&m.uv, &wavelength, c.seed);
            return Ok(BuiltCoupling { upper: ui, lower: li, kernels, adjust: c.adjust, distance: c.distance });
        }
        let cell = DVec2::new(lambda_min / 10.0, lambda_min / 10.0 * 0.75f64.sqrt());
        let cells = ((hi - lo) / cell).ceil().max(DVec2::ONE);
        let fine =
            crate::mesh::grid(hi - lo, (cells.x as u32, cells.y as u32), crate::mesh::GridPattern::Equilateral, 0.0);
        let points: Vec<DVec2> = fine.uv.iter().map(|u| *u + lo).collect();
        let wavelength: Vec<f64> = points.iter().map(|p| layout * local(*p)).collect();
        let kernels = kernels::build_kernels(&points, &fine.faces, &wavelength, c.seed);
        Ok(BuiltCoupling { upper: ui, lower: li, kernels, adjust: c.adjust, distance: c.distance })
    }
}
