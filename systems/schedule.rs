//! The frame: eleven chained stages (ARCHITECTURE.md 2). A stage runs only when the scene declares
//! what it works on: the constraint stages only with kernels, the walk only with anchors.
//! Remesh and PropertyResample run only for layers with `RemeshSettings`, Settle only after a
//! remesh changed a face.

use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{ScheduleLabel, SingleThreadedExecutor};
use skinsim::model::{Anchor, Kernel, PatchCaptures, PatchMotion, RemeshSettings, Stage, Timings, Unsettled};

use crate::log::{log_frame, wants_logging, RerunSink};
use crate::log_anchors::log_anchors;
use crate::log_contact::log_contact;
use crate::{anchors, assemble, capture, kernels, motion, properties, remesh, settle, solve, writeback};

#[derive(ScheduleLabel, Debug, Clone, PartialEq, Eq, Hash)]
pub struct Frame;

#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StageSet(pub Stage);

pub fn build_schedule() -> Schedule {
    let mut s = Schedule::new(Frame);
    // Heavy work runs in rayon inside systems; one executor thread avoids a second pool.
    s.set_executor(SingleThreadedExecutor::new());
    s.configure_sets(
        (
            StageSet(Stage::Motion).run_if(any_with_component::<PatchMotion>),
            StageSet(Stage::Remesh).run_if(any_with_component::<RemeshSettings>),
            StageSet(Stage::PropertyResample).run_if(any_with_component::<RemeshSettings>),
            StageSet(Stage::ConstraintResample).run_if(any_with_component::<Kernel>),
            StageSet(Stage::ConstraintAdjust).run_if(any_with_component::<Kernel>),
            StageSet(Stage::AnchorWalk).run_if(any_with_component::<Anchor>),
            StageSet(Stage::Assemble),
            StageSet(Stage::Settle).run_if(any_with_component::<Unsettled>),
            StageSet(Stage::Solve),
            StageSet(Stage::Writeback),
            StageSet(Stage::Log).run_if(wants_logging),
        )
            .chain(),
    );
    // Bodies first, then the layers embedded in them.
    s.add_systems(timed(Stage::Motion, (motion::apply_motions, motion::carry_embedded).chain()));
    s.add_systems(timed(Stage::Remesh, remesh::remesh_layers));
    s.add_systems(timed(Stage::PropertyResample, properties::resample_properties));
    s.add_systems(timed(Stage::ConstraintResample, kernels::resample_kernels));
    s.add_systems(timed(Stage::ConstraintAdjust, kernels::adjust_kernels));
    s.add_systems(timed(Stage::AnchorWalk, anchors::walk_anchors));
    s.add_systems(timed(Stage::Assemble, assemble::gather_packed));
    s.add_systems(timed(Stage::Settle, settle::settle_remeshed));
    s.add_systems(timed(Stage::Solve, solve::solve_patches));
    s.add_systems(timed(
        Stage::Writeback,
        (writeback::scatter_packed, capture::capture_prestrain.run_if(any_with_component::<PatchCaptures>)).chain(),
    ));
    s.add_systems(timed(
        Stage::Log,
        (
            log_frame,
            log_anchors.run_if(resource_exists::<RerunSink>).run_if(any_with_component::<Anchor>),
            log_contact.run_if(resource_exists::<RerunSink>).run_if(any_with_component::<skinsim::model::Contact>),
        )
            .chain(),
    ));
    s
}

/// A stage's systems between two timer systems that record its wall time in `Timings`.
fn timed<M>(
    stage: Stage,
    systems: impl IntoScheduleConfigs<bevy_ecs::system::ScheduleSystem, M>,
) -> bevy_ecs::schedule::ScheduleConfigs<bevy_ecs::system::ScheduleSystem> {
    (|mut t: ResMut<Timings>| t.begin(), systems, move |mut t: ResMut<Timings>| t.end(stage))
        .chain()
        .in_set(StageSet(stage))
}
