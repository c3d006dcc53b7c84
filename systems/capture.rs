//! Prestrain capture (H15 4.3, "make these wrinkles permanent"): after the solve of a
//! capture's frame, part of each element's current state becomes its rest state. Runs at the
//! end of Writeback, only in scenes that declare a capture.

use bevy_ecs::prelude::*;
use glam::{DMat2, DMat3, DVec2, DVec3};
use skinsim::model::*;
use skinsim::physics::hinge;
use skinsim::physics::prestrain::{hinge_capture, membrane_release, tet_release};

type CaptureLayer<'a> =
    (Option<&'a Bending>, Option<&'a LayerFaces>, Option<&'a LayerEdges>, Option<&'a LayerTets>, &'a mut TopologyEpoch);

#[allow(clippy::too_many_arguments)]
pub fn capture_prestrain(
    clock: Res<SimClock>,
    failure: Res<SimFailure>,
    patches: Query<&PatchCaptures>,
    mut layers: Query<CaptureLayer>,
    vertices: Query<(&Position, &MaterialPos)>,
    mut faces: Query<(&FaceVerts, &mut FaceRest, Option<&mut FacePrestrain>)>,
    mut hinges: Query<(&EdgeVerts, &mut Hinge)>,
    mut tets: Query<(&TetVerts, &mut TetRestShape, Option<&mut TetPrestrain>)>,
    mut commands: Commands,
) {
    if failure.0.is_some() {
        return;
    }
    let x = |e: Entity| vertices.get(e).map(|(p, _)| p.0).unwrap_or(DVec3::ZERO);
    let uv = |e: Entity| vertices.get(e).map(|(_, u)| u.0).unwrap_or(DVec2::ZERO);
    for capture in patches.iter().flat_map(|p| &p.0).filter(|c| c.frame == clock.frame) {
        let fraction = |centre: DVec2| capture.fraction * capture.map.as_ref().map_or(1.0, |m| m.sample(centre));
        for &layer in &capture.layers {
            let Ok((bending, lfaces, ledges, ltets, mut epoch)) = layers.get_mut(layer) else { continue };
            for &f in lfaces.map_or(&[][..], |l| l.entities()) {
                let Ok((fv, mut rest, f0)) = faces.get_mut(f) else { continue };
                let w = fraction(fv.0.iter().map(|&v| uv(v)).sum::<DVec2>() / 3.0);
                let release = membrane_release(&rest.0, &fv.0.map(x), w);
                rest.0.b *= release;
                match f0 {
                    Some(mut f0) => f0.0 *= release,
                    None => {
                        commands.entity(f).insert(FacePrestrain(DMat2::IDENTITY * release));
                    }
                }
            }
            if let (Some(b), Some(edges)) = (bending, ledges) {
                for &e in edges.entities() {
                    let Ok((ev, mut h)) = hinges.get_mut(e) else { continue };
                    let v = [ev.0[0], ev.0[1], h.opposite[0], h.opposite[1]];
                    let p = hinge::positions(v, h.image.map(|[a, c]| (a, c)), x);
                    let w = fraction(0.5 * (uv(ev.0[0]) + uv(ev.0[1])));
                    h.rest = hinge_capture(b.model, &h.rest, &p, w);
                }
            }
            for &t in ltets.map_or(&[][..], |l| l.entities()) {
                let Ok((tv, mut rest, f0)) = tets.get_mut(t) else { continue };
                let w = fraction(tv.0.iter().map(|&v| uv(v)).sum::<DVec2>() / 4.0);
                let release = tet_release(&rest.0, &tv.0.map(x), w);
                rest.0.b *= release;
                match f0 {
                    Some(mut f0) => f0.0 *= release,
                    None => {
                        commands.entity(t).insert(TetPrestrain(DMat3::IDENTITY * release));
                    }
                }
            }
            // The packed solver body holds copies of the rest data: have Assemble rebuild it.
            epoch.0 += 1;
        }
    }
}
