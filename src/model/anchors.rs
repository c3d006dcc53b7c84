//! KCK18 anchors (ARCHITECTURE.md 3): one entity per skin vertex and per skin face barycentre,
//! each holding a point on a kinematic body surface.

use bevy_ecs::prelude::*;
use glam::DVec3;

use crate::coupling::walk::{BodySurface, Stop, SurfacePoint};

/// How anchors follow the skin's pull (KCK18 sections 1-2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum AnchorMethod {
    /// 2D ray tracing over the body surface (KCK18 section 2).
    #[default]
    Walk,
    /// "Projection springs": the closest point of the whole body.
    Project,
    /// Projection restricted to the faces within N vertex rings of the anchor's face.
    ProjectRing(u32),
}

/// On a skin layer: its anchors hold it to `body` (a kinematic layer), moved by `method`; each
/// frame an anchor is offered a* = a0 + slide (x_skin - a0).
#[derive(Component, Clone, Copy, Debug)]
pub struct Anchoring {
    pub body: Entity,
    pub method: AnchorMethod,
    pub slide: f64,
}

/// On a body layer: its triangles and adjacency for walking, and its rest positions (where
/// anchor jumps are measured: how far an anchor slid over the body's material).
#[derive(Component, Clone, Debug)]
pub struct AnchorBody {
    pub surface: BodySurface,
    pub rest: Vec<DVec3>,
    pub vertex_faces: Vec<Vec<u32>>,
}

/// What an anchor holds on the skin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SkinPoint {
    Vertex(Entity),
    /// A face barycentre: the mean of its three vertices.
    Face([Entity; 3]),
}

/// A zero-length spring from a skin point to a body surface point (KCK18 section 3).
#[derive(Component, Clone, Copy, Debug)]
pub struct Anchor {
    pub skin: SkinPoint,
    pub body: SurfacePoint,
    /// Spring stiffness (N/m).
    pub stiffness: f64,
}

/// What the last AnchorWalk did to an anchor: its world position, the displacement it was
/// offered (|a* - a0|, m), the surface path it walked (m; projection: 0) and its jump measured
/// on the body's rest surface (m).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct AnchorState {
    pub position: DVec3,
    pub step: f64,
    pub walked: f64,
    pub jump: f64,
}

/// Anchor -> skin layer.
#[derive(Component, Clone, Copy, Debug)]
#[relationship(relationship_target = LayerAnchors)]
pub struct AnchorOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = AnchorOf, linked_spawn)]
pub struct LayerAnchors(Vec<Entity>);

impl LayerAnchors {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

/// On a patch with anchors: what the last AnchorWalk did (written to stats.jsonl). Lengths in m.
#[derive(Component, Clone, Copy, Debug, Default, serde::Serialize)]
pub struct AnchorReport {
    pub anchors: usize,
    /// The largest displacement an anchor was offered, |a* - a0|.
    pub max_step: f64,
    /// The longest surface path walked (0 under projection).
    pub max_walked: f64,
    /// The largest jump over the body's rest surface, and the largest excess of a jump over
    /// the anchor's own step (a jump across a fold shows here).
    pub max_jump: f64,
    pub max_excess: f64,
    /// Walks that ended on a crease (a face met twice) and at the body's boundary.
    pub creases: usize,
    pub boundaries: usize,
}

impl AnchorReport {
    pub fn add(&mut self, s: &AnchorState, stop: Option<Stop>) {
        self.max_step = self.max_step.max(s.step);
        self.max_walked = self.max_walked.max(s.walked);
        self.max_jump = self.max_jump.max(s.jump);
        self.max_excess = self.max_excess.max(s.jump - s.step);
        match stop {
            Some(Stop::Crease) => self.creases += 1,
            Some(Stop::Boundary) => self.boundaries += 1,
            _ => {}
        }
    }
}
