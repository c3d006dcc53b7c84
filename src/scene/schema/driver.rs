//! A patch's drivers: pins, prescribed motions (compression, bending, blend shapes, poses, OBJ
//! sequences), attachments, plane strain, periodicity and captures; and vertex selections.

use serde::{Deserialize, Serialize};

use super::{default_one, default_true, Axis};

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub enum Side {
    XMin,
    XMax,
    YMin,
    YMax,
    ZMin,
    ZMax,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum Select {
    All,
    /// Vertices on the given sides of the layer's bounding box.
    Sides(Vec<Side>),
    /// Vertices inside a box (length units).
    Box {
        min: (f64, f64, f64),
        max: (f64, f64, f64),
    },
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Dofs {
    #[serde(default = "default_true")]
    pub x: bool,
    #[serde(default = "default_true")]
    pub y: bool,
    #[serde(default = "default_true")]
    pub z: bool,
}

impl Default for Dofs {
    fn default() -> Self {
        Dofs { x: true, y: true, z: true }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum DriverSpec {
    /// Prescribes coordinates of selected vertices (held at their driven position).
    Pin {
        layer: String,
        select: Select,
        #[serde(default)]
        dofs: Dofs,
    },
    /// Uniform compression of the listed layers along an axis about the patch centre:
    /// `keyframes` are (frame, strain); strain 0.1 shortens by 10 %. Moves prescribed
    /// coordinates; with `predict`, free vertices get the same incremental map as a guess
    /// (quasistatic modes: implicit Euler starts from its predictor x_n + h v_n).
    Compress {
        layers: Vec<String>,
        #[serde(default)]
        axis: Axis,
        keyframes: Vec<(u32, f64)>,
        #[serde(default = "default_true")]
        predict: bool,
    },
    /// Bends the listed layers into a cylinder about an axis through the patch centre:
    /// `keyframes` are (frame, curvature in 1 / length unit). Moves prescribed coordinates.
    Bend {
        layers: Vec<String>,
        #[serde(default = "axis_y")]
        axis: Axis,
        keyframes: Vec<(u32, f64)>,
    },
    /// A procedural joint (issue 24): the listed layers turn about the hinge line through `pivot`
    /// (length units, the patch's frame) along `axis` by `keyframes` (frame, degrees), the part
    /// beyond the joint along `along` rigidly, a zone `width` long (length units) centred on the
    /// pivot blending smoothly from none to all: a finger bending at its knuckle.
    Joint {
        layers: Vec<String>,
        pivot: (f64, f64, f64),
        #[serde(default = "axis_y")]
        axis: Axis,
        #[serde(default)]
        along: Axis,
        width: f64,
        keyframes: Vec<(u32, f64)>,
    },
    /// Zero-length springs from every vertex of `layer` to the vertex of `to` at the same
    /// material position; `stiffness` per unit area (stress / length units).
    Attach { layer: String, to: String, stiffness: f64 },
    /// Plane strain along `axis` (H15 6.1): the axis coordinate of every vertex of the layers
    /// is held, and vertices that differ only along the axis share their other coordinates, so
    /// a strip one cell deep deforms as a 2D section (no twist, no transverse curvature).
    PlaneStrain {
        layers: Vec<String>,
        #[serde(default = "axis_y")]
        axis: Axis,
    },
    /// Periodic along `axis`: vertices on the max side share their other coordinates with the
    /// vertex at the same place on the min side, so waves continue across (a domain of a whole
    /// number of wavelengths). The axis coordinate itself is left to Pin and Compress.
    Periodic {
        layers: Vec<String>,
        #[serde(default)]
        axis: Axis,
    },
    /// Blend shapes (LK14 5.3) on a layer, usually the kinematic base under a LK14 patch:
    /// x = X + sum over targets of w(frame) (target - X). Moves the layer's prescribed
    /// coordinates (every coordinate of a kinematic layer).
    BlendShape {
        layer: String,
        targets: Vec<BlendTargetSpec>,
        #[serde(default)]
        interpolation: crate::model::Interpolation,
        /// The declared range of every weight; a keyframe outside it is an error.
        #[serde(default = "unit_range")]
        range: (f64, f64),
    },
    /// Poses a kinematic body (KCK18 scenes): the pose at weight w is evaluated exactly (an
    /// elbow bent by w x angle), not blended linearly between rest and target.
    Articulate {
        layer: String,
        pose: PoseSpec,
        weights: Vec<(u32, f64)>,
        #[serde(default)]
        interpolation: crate::model::Interpolation,
    },
    /// An OBJ sequence (paths relative to the scene, length units): frame `start + i` takes the
    /// positions of `files[i]`, the last file holds after; the same vertex count and order as
    /// the layer's mesh.
    ObjSequence {
        layer: String,
        files: Vec<String>,
        #[serde(default)]
        start: u32,
    },
    /// Moves a glTF body (issue 62) by its own rig: an animation clip of the asset (`clip`, its
    /// time = (frame - `start`) x frame_time x `speed`) and/or keyframed joint rotations and
    /// morph-target weights by name, skinned by linear blend skinning or dual quaternions.
    /// Morph targets act before skinning, as glTF orders them.
    Rig {
        layer: String,
        #[serde(default)]
        clip: Option<String>,
        #[serde(default)]
        start: u32,
        #[serde(default = "default_one")]
        speed: f64,
        /// Rotations about an axis of the joint's own (local) frame, on top of the clip's.
        #[serde(default)]
        joints: Vec<JointKeysSpec>,
        /// Morph-target weights (replacing the clip's for that target).
        #[serde(default)]
        morphs: Vec<MorphKeysSpec>,
        #[serde(default)]
        skinning: SkinningSpec,
        #[serde(default)]
        interpolation: crate::model::Interpolation,
    },
    /// Makes wrinkles permanent (H15 4.3): after the solve of `frame`, `fraction` of each
    /// element's current stretch becomes its prestrain (F0 <- F0 U^-fraction) and each hinge's
    /// rest bend moves that fraction towards its current bend. `map` paints the fraction
    /// (greyscale PNG over the layer's rectangle, white = 1).
    Capture {
        layers: Vec<String>,
        frame: u32,
        #[serde(default = "default_one")]
        fraction: f64,
        #[serde(default)]
        map: Option<String>,
    },
}

/// A procedural body pose (about the centre of the layer's bounding box; angles in degrees).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum PoseSpec {
    /// A tube along x bends upwards from its centre along an arc of `bend_radius` (length
    /// units); below the tube radius the inside of the elbow pinches and then folds through.
    Elbow { angle: f64, bend_radius: f64 },
    /// The part beyond the centre (x) folds upwards about a line along y: at 180 degrees the
    /// crease closes to zero width, past it the halves pass through each other.
    Fold { angle: f64 },
}

/// How a glTF skin blends its joints' transforms (PHYSICS.md 7).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
pub enum SkinningSpec {
    /// Linear blend skinning (the glTF specification's): collapses the inside of a bent or
    /// twisted joint.
    #[default]
    Linear,
    /// Dual-quaternion skinning (Kavan et al. 2007): keeps volume at twisting joints.
    DualQuaternion,
}

/// A joint of a glTF skin turned about `axis` (its own frame; normalised) by keyframed angles
/// (frame, degrees).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "JointKeys")]
pub struct JointKeysSpec {
    pub joint: String,
    pub axis: (f64, f64, f64),
    pub keyframes: Vec<(u32, f64)>,
}

/// A morph target of a glTF mesh weighted by keyframes (frame, weight).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "MorphKeys")]
pub struct MorphKeysSpec {
    pub target: String,
    pub keyframes: Vec<(u32, f64)>,
}

fn unit_range() -> (f64, f64) {
    (0.0, 1.0)
}

/// One blend-shape target and its weight keyframes (frame, weight).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Target")]
pub struct BlendTargetSpec {
    pub shape: TargetShape,
    pub weights: Vec<(u32, f64)>,
}

/// The full (weight 1) pose of a target, about the centre of the layer's bounding box. The
/// procedural shapes mimic LK14 fig. 5-1.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum TargetShape {
    /// Shortens the layer along `axis` by `strain` (0.3: 30 %).
    Compress {
        #[serde(default)]
        axis: Axis,
        strain: f64,
    },
    /// Turns the layer about its normal through the centre by `angle` degrees at the centre,
    /// falling smoothly to none at `radius` (length units; default half the smaller side): the
    /// shear of skin twisted over a turning limb.
    Twist {
        angle: f64,
        #[serde(default)]
        radius: Option<f64>,
    },
    /// Draws the skin within `radius` towards the centre (by `squeeze` times the distance at
    /// the centre, smoothly less outwards) and lifts it by `lift` (length units): a pinch while
    /// pulling up. With `between: Some(X)` the skin is drawn in along that axis only, as between
    /// two fingers, and a squeeze above 1 folds it over itself (the middle lies over its sides).
    Pinch {
        radius: f64,
        squeeze: f64,
        lift: f64,
        #[serde(default)]
        between: Option<Axis>,
    },
    /// A target mesh (path relative to the scene, length units): the same vertices in the same
    /// order as the layer's mesh.
    Obj(String),
}

fn axis_y() -> Axis {
    Axis::Y
}
