//! ConstraintResample and ConstraintAdjust (LK14 4.2): a kernel's weights are recomputed only
//! when it is new or when the mesh of one of its layers changed (its `TopologyEpoch` was
//! written), so a remesh plugs in by bumping the epoch.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::DVec2;
use skinsim::coupling::geodesic::SurfaceSpace;
use skinsim::coupling::kernels::{adjust, sample, vertex_areas, KernelDistance, Sample, SupportIndex};
use skinsim::model::*;

use crate::layer_arrays::LayerArrays;

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
    rest: Query<&RestPos>,
    faces: Query<&FaceVerts>,
) {
    let mut spaces: HashMap<Entity, LayerSpace> = HashMap::new();
    let changed = |l: Entity| layers.get(l).is_ok_and(|(epoch, ..)| epoch.is_changed());
    let stale = |k: &Ref<Kernel>| k.is_changed() || changed(k.upper) || changed(k.lower);
    // The rest surfaces that stale geodesic kernels sample, each with one point locator.
    let mut surfaces: HashMap<Entity, (Vec<Entity>, SurfaceSpace)> = HashMap::new();
    for (kernel, _) in &kernels {
        if kernel.distance == KernelDistance::Geodesic && stale(&kernel) {
            for layer in [kernel.upper, kernel.lower] {
                surfaces.entry(layer).or_insert_with(|| surface_space(layer, &layers, &points, &rest, &faces));
            }
        }
    }
    let locators: HashMap<Entity, _> = surfaces.iter().map(|(&l, (_, space))| (l, space.locator())).collect();
    for (kernel, mut samples) in &mut kernels {
        if !stale(&kernel) {
            continue;
        }
        let (centre, radius) = (kernel.shape.centre, kernel.shape.radius);
        *samples = match kernel.distance {
            KernelDistance::Planar => {
                let mut on = |layer: Entity| -> LayerWeights {
                    let space = spaces.entry(layer).or_insert_with(|| layer_space(layer, &layers, &points, &faces));
                    let s = sample(&space.index, &space.area, centre, radius);
                    s.vertices.iter().zip(&s.weights).map(|(&v, &w)| (space.vertices[v as usize], w)).collect()
                };
                KernelSamples { upper: on(kernel.upper), lower: on(kernel.lower), chart: Default::default() }
            }
            KernelDistance::Geodesic => {
                let on = |layer: Entity| -> (LayerWeights, Vec<DVec2>) {
                    let (vertices, space) = &surfaces[&layer];
                    let s = space.sample(&locators[&layer], centre, radius);
                    let weights = s.sample.vertices.iter().zip(&s.sample.weights);
                    (weights.map(|(&v, &w)| (vertices[v as usize], w)).collect(), s.chart)
                };
                let ((upper, cu), (lower, cl)) = (on(kernel.upper), on(kernel.lower));
                KernelSamples { upper, lower, chart: [cu, cl] }
            }
        };
    }
}

/// One layer's rest surface for geodesic kernels, with its vertices in index order.
fn surface_space(
    layer: Entity,
    layers: &Query<LayerMeshItems>,
    points: &Query<&MaterialPos>,
    rest: &Query<&RestPos>,
    faces: &Query<&FaceVerts>,
) -> (Vec<Entity>, SurfaceSpace) {
    let (_, verts, lfaces) = layers.get(layer).expect("a kernel's layer");
    let a = LayerArrays::queried(verts, lfaces, faces);
    let uv = a.map(|&v| points.get(v).map_or(DVec2::ZERO, |p| p.0));
    let x = a.map(|&v| rest.get(v).map_or(glam::DVec3::ZERO, |p| p.0));
    let space = SurfaceSpace::new(&x, &uv, &a.tris);
    (a.vertices, space)
}

fn layer_space(
    layer: Entity,
    layers: &Query<LayerMeshItems>,
    points: &Query<&MaterialPos>,
    faces: &Query<&FaceVerts>,
) -> LayerSpace {
    let (_, verts, lfaces) = layers.get(layer).expect("a kernel's layer");
    let a = LayerArrays::queried(verts, lfaces, faces);
    let pts = a.map(|&v| points.get(v).map_or(DVec2::ZERO, |p| p.0));
    let area = vertex_areas(&pts, &a.tris);
    LayerSpace { index: SupportIndex::new(&pts), vertices: a.vertices, area }
}

pub fn adjust_kernels(
    mut kernels: Query<(&Kernel, Ref<KernelSamples>, &mut KernelWeights)>,
    points: Query<&MaterialPos>,
) {
    for (kernel, samples, mut weights) in &mut kernels {
        if !samples.is_changed() {
            continue;
        }
        let side = |w: &LayerWeights, chart: &[DVec2]| {
            let mut s = Sample { vertices: (0..w.len() as u32).collect(), weights: w.iter().map(|x| x.1).collect() };
            let outcome = kernel.adjust.then(|| match kernel.distance {
                KernelDistance::Planar => {
                    let pts: Vec<DVec2> = w.iter().map(|(v, _)| points.get(*v).map_or(DVec2::ZERO, |p| p.0)).collect();
                    adjust(&pts, &mut s, kernel.shape.target)
                }
                // In the tangent chart, centred on the kernel (or its cut centroid's offset).
                KernelDistance::Geodesic => adjust(chart, &mut s, kernel.shape.target - kernel.shape.centre),
            });
            let out: LayerWeights = w.iter().zip(&s.weights).map(|((v, _), &x)| (*v, x)).collect();
            (out, outcome)
        };
        let (upper, a) = side(&samples.upper, &samples.chart[0]);
        let (lower, b) = side(&samples.lower, &samples.chart[1]);
        *weights = KernelWeights { upper, lower, adjusted: [a, b] };
    }
}
