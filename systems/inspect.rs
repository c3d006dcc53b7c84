//! Reading a running simulation's layers and anchors back out of its World (the report and
//! bake tools, and the tests).

use bevy_ecs::prelude::*;
use skinsim::model::*;

use crate::layer_arrays::LayerArrays;
use crate::Simulation;

/// A surface layer at the current frame (`Simulation::layer_snapshot`).
#[derive(Clone, Debug, Default)]
pub struct SurfaceSnapshot {
    /// Material positions (m).
    pub uv: Vec<glam::DVec2>,
    /// The asset's own UVs, where every vertex has them.
    pub asset_uv: Option<Vec<glam::DVec2>>,
    pub pos: Vec<glam::DVec3>,
    pub rest: Vec<glam::DVec3>,
    pub faces: Vec<[u32; 3]>,
}

impl Simulation {
    /// A shell layer's own triangle mesh: material positions, positions, faces (indices into
    /// the first two). Empty for an unknown layer.
    pub fn layer_mesh(&mut self, patch: &str, layer: &str) -> (Vec<glam::DVec2>, Vec<glam::DVec3>, Vec<[u32; 3]>) {
        let Some(l) = self.find_layer(patch, layer) else { return Default::default() };
        let (a, world) = (LayerArrays::of(&self.world, l), &self.world);
        let uv = a.map(|&v| world.get::<MaterialPos>(v).unwrap().0);
        let x = a.map(|&v| world.get::<Position>(v).unwrap().0);
        (uv, x, a.tris)
    }

    /// Every vertex a layer's elements use (its own and those it shares with the layer below),
    /// as (material position, position), in first-use order.
    pub fn layer_points(&mut self, patch: &str, layer: &str) -> Vec<(glam::DVec2, glam::DVec3)> {
        let Some(l) = self.find_layer(patch, layer) else { return Vec::new() };
        let mut used: Vec<Entity> =
            self.world.get::<LayerVertices>(l).map(|v| v.entities().to_vec()).unwrap_or_default();
        if let Some(faces) = self.world.get::<LayerFaces>(l) {
            used.extend(faces.entities().iter().filter_map(|&f| self.world.get::<FaceVerts>(f)).flat_map(|f| f.0));
        }
        if let Some(tets) = self.world.get::<LayerTets>(l) {
            used.extend(tets.entities().iter().filter_map(|&t| self.world.get::<TetVerts>(t)).flat_map(|t| t.0));
        }
        let mut seen = std::collections::HashSet::new();
        used.retain(|e| seen.insert(*e));
        used.iter()
            .map(|&e| (self.world.get::<MaterialPos>(e).unwrap().0, self.world.get::<Position>(e).unwrap().0))
            .collect()
    }

    fn find_layer(&mut self, patch: &str, layer: &str) -> Option<Entity> {
        let mut q = self.world.query::<(Entity, &Layer, &LayerOf)>();
        let found: Vec<(Entity, Entity)> =
            q.iter(&self.world).filter(|(_, l, _)| l.name == layer).map(|(e, _, of)| (e, of.0)).collect();
        found.into_iter().find(|(_, p)| self.world.get::<Patch>(*p).is_some_and(|p| p.name == patch)).map(|(e, _)| e)
    }

    /// A surface layer's triangles over the vertices they use: (material positions, positions,
    /// faces indexing those). Empty for a layer without faces.
    pub fn layer_surface(&mut self, patch: &str, layer: &str) -> (Vec<glam::DVec2>, Vec<glam::DVec3>, Vec<[u32; 3]>) {
        let Some(l) = self.find_layer(patch, layer) else { return Default::default() };
        let Some(faces) = self.world.get::<LayerFaces>(l) else { return Default::default() };
        let tris: Vec<[Entity; 3]> =
            faces.entities().iter().filter_map(|&f| self.world.get::<FaceVerts>(f)).map(|f| f.0).collect();
        let mut index = std::collections::HashMap::new();
        let (mut uv, mut pos) = (Vec::new(), Vec::new());
        let faces = tris
            .iter()
            .map(|t| {
                t.map(|e| {
                    *index.entry(e).or_insert_with(|| {
                        uv.push(self.world.get::<MaterialPos>(e).map_or(glam::DVec2::ZERO, |m| m.0));
                        pos.push(self.world.get::<Position>(e).map_or(glam::DVec3::ZERO, |p| p.0));
                        (uv.len() - 1) as u32
                    })
                })
            })
            .collect();
        (uv, pos, faces)
    }

    /// `layer_surface` with, in the same numbering, the rest positions and the asset's own UVs
    /// where every vertex has them (a character's layers).
    pub fn layer_snapshot(&mut self, patch: &str, layer: &str) -> SurfaceSnapshot {
        let Some(l) = self.find_layer(patch, layer) else { return Default::default() };
        let Some(faces) = self.world.get::<LayerFaces>(l) else { return Default::default() };
        let tris: Vec<[Entity; 3]> =
            faces.entities().iter().filter_map(|&f| self.world.get::<FaceVerts>(f)).map(|f| f.0).collect();
        let mut index = std::collections::HashMap::new();
        let mut order = Vec::new();
        let faces = tris
            .iter()
            .map(|t| {
                t.map(|e| {
                    *index.entry(e).or_insert_with(|| {
                        order.push(e);
                        (order.len() - 1) as u32
                    })
                })
            })
            .collect();
        let w = &self.world;
        SurfaceSnapshot {
            uv: order.iter().map(|&e| w.get::<MaterialPos>(e).map_or(glam::DVec2::ZERO, |m| m.0)).collect(),
            asset_uv: order.iter().map(|&e| w.get::<AssetUv>(e).map(|u| u.0)).collect(),
            pos: order.iter().map(|&e| w.get::<Position>(e).map_or(glam::DVec3::ZERO, |p| p.0)).collect(),
            rest: order.iter().map(|&e| w.get::<RestPos>(e).map_or(glam::DVec3::ZERO, |p| p.0)).collect(),
            faces,
        }
    }

    /// The names of every patch's layers, bottom to top, with their kinds.
    pub fn layers(&mut self) -> Vec<(String, String, LayerKind)> {
        let mut q = self.world.query::<(&Layer, &LayerOf)>();
        let mut out: Vec<(u32, u32, String, String, LayerKind)> = q
            .iter(&self.world)
            .filter_map(|(l, of)| {
                let p = self.world.get::<Patch>(of.0)?;
                Some((p.index, l.index, p.name.clone(), l.name.clone(), l.kind))
            })
            .collect();
        out.sort_by_key(|x| (x.0, x.1));
        out.into_iter().map(|x| (x.2, x.3, x.4)).collect()
    }

    /// Positions of a layer's own vertices in spawn order.
    pub fn layer_positions(&mut self, patch: &str, layer: &str) -> Vec<glam::DVec3> {
        let mut q = self.world.query::<(&Layer, &LayerOf, &LayerVertices)>();
        let mut pq = self.world.query::<&Patch>();
        let mut out = Vec::new();
        for (l, of, verts) in q.iter(&self.world) {
            if l.name == layer && pq.get(&self.world, of.0).map(|p| p.name == patch).unwrap_or(false) {
                out = verts.entities().to_vec();
            }
        }
        out.iter().map(|e| self.world.get::<Position>(*e).unwrap().0).collect()
    }

    /// Every anchor of a patch (KCK18): its body point and what the last walk did.
    pub fn anchors(&mut self, patch: &str) -> Vec<(skinsim::coupling::walk::SurfacePoint, AnchorState)> {
        let mut q = self.world.query::<(&Anchor, &AnchorState, &AnchorOf)>();
        let mut out = Vec::new();
        for (a, s, of) in q.iter(&self.world) {
            let in_patch = self.world.get::<LayerOf>(of.0).and_then(|p| self.world.get::<Patch>(p.0));
            if in_patch.is_some_and(|p| p.name == patch) {
                out.push((a.body, *s));
            }
        }
        out
    }
}
