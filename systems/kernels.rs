//! ConstraintResample and ConstraintAdjust (LK14 4.2): a kernel's weights are recomputed only
//! when it is new or when the mesh of one of its layers changed (its `TopologyEpoch` was
//! written), so a remesh plugs in by bumping the epoch.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::DVec2;
use skinsim::coupling::kernels::{adjust, sample, vertex_areas, Sample, SupportIndex};
use skinsim::model::*;
use skinsim::solve::constraints::{vertex_rings, Constraints, KernelRows};
use skinsim::solve::SolverBody;

/// One layer's material-space mesh, indexed for support queries.
struct LayerSpace {
    vertices: Vec<Entity>,
    area: Vec<f64>,
    index: SupportIndex,
}

type LayerMeshItems<'a> = (Ref<'a, TopologyEpoch>, &'a LayerVertices, Option<&'a LayerFaces>);

pub fn resample_kernels(
    mut kernels: Query<(Ref<Kernel>, &mut KernelSamples)>,
    layers: Query<LayerMeshItems>,
    points: Query<&MaterialPos>,
    faces: Query<&FaceVerts>,
) {
    let mut spaces: HashMap<Entity, LayerSpace> = HashMap::new();
    let changed = |l: Entity| layers.get(l).is_ok_and(|(epoch, ..)| epoch.is_changed());
    for (kernel, mut samples) in &mut kernels {
        if !(kernel.is_changed() || changed(kernel.upper) || changed(kernel.lower)) {
            continue;
        }
        let mut on = |layer: Entity| -> LayerWeights {
            let space = spaces.entry(layer).or_insert_with(|| layer_space(layer, &layers, &points, &faces));
            let s = sample(&space.index, &space.area, kernel.shape.centre, kernel.shape.radius);
            s.vertices.iter().zip(&s.weights).map(|(&v, &w)| (space.vertices[v as usize], w)).collect()
        };
        let upper = on(kernel.upper);
        let lower = on(kernel.lower);
        *samples = KernelSamples { upper, lower };
    }
}

fn layer_space(
    layer: Entity,
    layers: &Query<LayerMeshItems>,
    points: &Query<&MaterialPos>,
    faces: &Query<&FaceVerts>,
) -> LayerSpace {
    let (_, verts, lfaces) = layers.get(layer).expect("a kernel's layer");
    let vertices = verts.entities().to_vec();
    let slot: HashMap<Entity, u32> = vertices.iter().enumerate().map(|(i, &e)| (e, i as u32)).collect();
    let pts: Vec<DVec2> = vertices.iter().map(|&v| points.get(v).map_or(DVec2::ZERO, |p| p.0)).collect();
    let tris: Vec<[u32; 3]> = lfaces
        .map(|f| f.entities().iter().filter_map(|&f| faces.get(f).ok()).map(|fv| fv.0.map(|e| slot[&e])).collect())
        .unwrap_or_default();
    let area = vertex_areas(&pts, &tris);
    LayerSpace { index: SupportIndex::new(&pts), vertices, area }
}

pub fn adjust_kernels(
    mut kernels: Query<(&Kernel, Ref<KernelSamples>, &mut KernelWeights)>,
    points: Query<&MaterialPos>,
) {
    for (kernel, samples, mut weights) in &mut kernels {
        if !samples.is_changed() {
            continue;
        }
        let side = |w: &LayerWeights| {
            let pts: Vec<DVec2> = w.iter().map(|(v, _)| points.get(*v).map_or(DVec2::ZERO, |p| p.0)).collect();
            let mut s = Sample { vertices: (0..w.len() as u32).collect(), weights: w.iter().map(|x| x.1).collect() };
            let outcome = kernel.adjust.then(|| adjust(&pts, &mut s, kernel.shape.target));
            let out: LayerWeights = w.iter().zip(&s.weights).map(|((v, _), &x)| (*v, x)).collect();
            (out, outcome)
        };
        let (upper, a) = side(&samples.upper);
        let (lower, b) = side(&samples.lower);
        *weights = KernelWeights { upper, lower, adjusted: [a, b] };
    }
}

/// A kernel and its (adjusted) weights, read by Assemble.
pub(crate) type KernelItems<'a> = (&'a Kernel, Ref<'a, KernelWeights>);

/// Packs the kernels' weights into constraint rows (LK14 eq. 4.1). A lower vertex's normal
/// offset is the distance between the layers' mid-surfaces, half the sum of their thicknesses
/// (a kinematic layer is a surface: thickness 0), each scaled by its property map at the kernel
/// centre.
pub(crate) fn kernel_rows(
    body: &SolverBody,
    patch_kernels: &PatchKernels,
    kernels: &Query<KernelItems>,
    layers: &Query<crate::assemble::LayerItems>,
    faces: &Query<(&FaceVerts, Option<&FaceRest>, Option<&ModulusScale>)>,
    thickness: &Query<(&Thickness, Option<&LayerProperties>)>,
) -> Constraints {
    let index: HashMap<Entity, u32> = body.vertices.iter().enumerate().map(|(i, &e)| (e, i as u32)).collect();
    let packed_faces = |layer: Entity| -> Vec<[u32; 3]> {
        let Ok((.., Some(lf), _, _, _, _, _)) = layers.get(layer) else { return Vec::new() };
        lf.entities().iter().filter_map(|&f| faces.get(f).ok()).map(|(fv, ..)| fv.0.map(|e| index[&e])).collect()
    };
    let half = |l: Entity, at: DVec2| thickness.get(l).map_or(0.0, |(t, p)| 0.5 * t.0 * factors_at(p, at).thickness);
    let mut rings: HashMap<Entity, HashMap<u32, Vec<[u32; 3]>>> = HashMap::new();
    let mut rows = Vec::new();
    for &k in patch_kernels.entities() {
        let Ok((kernel, weights)) = kernels.get(k) else { continue };
        if weights.upper.is_empty() || weights.lower.is_empty() {
            continue; // a kernel with an empty support on either layer constrains nothing
        }
        let ring = rings.entry(kernel.lower).or_insert_with(|| vertex_rings(&packed_faces(kernel.lower)));
        let pack = |w: &LayerWeights| -> Vec<(u32, f64)> { w.iter().map(|(v, x)| (index[v], *x)).collect() };
        let offset = half(kernel.upper, kernel.shape.centre) + half(kernel.lower, kernel.shape.centre);
        rows.push(KernelRows::new(pack(&weights.upper), &pack(&weights.lower), offset, ring, &body.fixed));
    }
    Constraints::new(rows, &body.x)
}
