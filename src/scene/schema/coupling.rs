//! LK14 couplings (constraint kernels) and KCK18 anchors between a patch's layers.

use serde::{Deserialize, Serialize};

use super::{default_one, default_true, MapSource};

/// KCK18 sliding skin: zero-length springs from every vertex and face barycentre of the shell
/// layer `skin` to points on the kinematic layer `body`, bound to the closest body point at
/// load. Each frame an anchor is offered a* = a0 + slide (x_skin - a0) and moves to it over the
/// body by `method`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Anchors")]
pub struct AnchorSpec {
    pub skin: String,
    pub body: String,
    /// Stiffness per unit skin area (stress / length units). A face of area A gives k A / 2 to
    /// its barycentre anchor and k A / 6 to each of its vertex anchors (all to the vertices
    /// without face anchors).
    pub stiffness: f64,
    #[serde(default)]
    pub method: crate::model::AnchorMethod,
    /// 1: the anchor follows the skin's tangential pull fully each frame; 0: it never slides.
    #[serde(default = "default_one")]
    pub slide: f64,
    /// Anchors at face barycentres too (KCK18 section 3: vertex anchors alone let a face
    /// straddle a crease). Off only to show that.
    #[serde(default = "default_true")]
    pub faces: bool,
    /// The farthest a skin point may start from the body (length units); default 5 % of the
    /// body's bounding-box diagonal. Farther is an error.
    #[serde(default)]
    pub max_distance: Option<f64>,
    /// Paints the stiffness: factor = lo + (hi - lo) x red of `map`, sampled at each anchor's
    /// skin point in the skin's material space.
    #[serde(default)]
    pub stiffness_map: Option<StiffnessMapSpec>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "StiffnessMap")]
pub struct StiffnessMapSpec {
    pub map: MapSource,
    pub range: (f64, f64),
}

/// Constraint kernels that hold `upper` to `lower` at frequencies below the critical
/// wavelength (LK14 chapter 4): clustered once at load, resampled whenever either mesh changes.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Coupling")]
pub struct CouplingSpec {
    /// A shell layer.
    pub upper: String,
    /// A shell or kinematic layer (the blend-shape base).
    pub lower: String,
    pub wavelength: WavelengthSpec,
    /// Seed of the first cluster centre (LK14 4.1).
    #[serde(default)]
    pub seed: u64,
    /// Adjust the sampled weights so their centroid is the kernel centre (LK14 4.2.1). Off only
    /// to measure what the adjustment does.
    #[serde(default = "default_true")]
    pub adjust: bool,
    /// `Planar` (default): kernels measured in material space (LK14 4.1); `Geodesic`: on each
    /// layer's rest surface (LK14 6.2), for curved layers whose UVs are distorted.
    #[serde(default)]
    pub distance: crate::coupling::kernels::KernelDistance,
}

/// Where a coupling's critical wavelength comes from.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum WavelengthSpec {
    /// A declared wavelength (length units), the same everywhere.
    Constant(f64),
    /// LK14 eq. 3.1: constant x (h_upper h_lower)^(1/2) (E_upper / E_lower)^(1/6), from the two
    /// layers' materials; `lower` = (young, thickness) stands in for a kinematic lower layer's
    /// (the substructure under a blend shape: LK14 uses 0.5 MPa, 15 mm).
    Eq31 {
        constant: f64,
        #[serde(default)]
        lower: Option<(f64, f64)>,
    },
    /// Stiff film on a deep substrate: 2 pi h (Ebar_f / (3 Ebar_s))^(1/3), the film the upper
    /// layer, `substrate` = (young, poisson) of the foundation.
    Film { substrate: (f64, f64) },
}
