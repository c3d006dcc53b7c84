//! A World with a spawned scene and the frame schedule: what the CLI and the tests drive.

use bevy_ecs::prelude::*;
use serde::Serialize;
use skinsim::model::*;
use skinsim::scene::{spawn, BuiltScene};

use crate::schedule::build_schedule;

/// One line of stats.jsonl.
#[derive(Clone, Debug, Serialize)]
pub struct FrameStats {
    pub frame: u32,
    pub time: f64,
    pub patches: Vec<PatchReport>,
    pub timings_ms: serde_json::Map<String, serde_json::Value>,
}

impl FrameStats {
    /// A stage's wall time in this frame (ms; 0 for a stage that did not run).
    pub fn timing(&self, stage: Stage) -> f64 {
        self.ms(stage.key())
    }

    /// The frame's wall time (ms).
    pub fn total_ms(&self) -> f64 {
        self.ms(TOTAL)
    }

    fn ms(&self, key: &str) -> f64 {
        let value = self.timings_ms.get(key).and_then(|v| v.as_f64());
        value.unwrap_or_else(|| panic!("stats hold no timing \"{key}\""))
    }
}

/// A stats line with every wall time (keys ending in `ms`, at any depth) left out: what two runs
/// of a scene at one thread count agree on bit for bit (a resumed one included).
pub fn without_timings(mut line: serde_json::Value) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(map) => {
                map.retain(|k, _| !k.ends_with("ms"));
                map.values_mut().for_each(strip);
            }
            serde_json::Value::Array(list) => list.iter_mut().for_each(strip),
            _ => {}
        }
    }
    strip(&mut line);
    line
}

/// The key of the frame's wall time in `timings_ms` (beside every stage's `Stage::key`).
pub const TOTAL: &str = "total";

pub struct Simulation {
    pub world: World,
    pub schedule: Schedule,
    pub patches: Vec<Entity>,
}

impl Simulation {
    pub fn new(scene: &BuiltScene) -> Self {
        let mut world = World::new();
        let patches = spawn(&mut world, scene);
        world.init_resource::<LogState>();
        Simulation { world, schedule: build_schedule(), patches }
    }

    /// Computes the next frame.
    pub fn step(&mut self) -> FrameStats {
        {
            let mut clock = self.world.resource_mut::<SimClock>();
            clock.frame += 1;
            clock.time = clock.frame as f64 * clock.dt;
        }
        self.world.resource_mut::<Timings>().reset();
        let start = std::time::Instant::now();
        self.schedule.run(&mut self.world);
        let total = start.elapsed().as_secs_f64() * 1e3;
        let clock = *self.world.resource::<SimClock>();
        let timings = self.world.resource::<Timings>();
        let mut timings_ms = serde_json::Map::new();
        for stage in Stage::ALL {
            timings_ms.insert(stage.key().into(), timings.get(stage).into());
        }
        timings_ms.insert(TOTAL.into(), total.into());
        FrameStats {
            frame: clock.frame,
            time: clock.time,
            patches: self.world.resource::<FrameReport>().patches.clone(),
            timings_ms,
        }
    }

    /// The state after the last frame (`checkpoint`).
    pub fn checkpoint(&mut self) -> crate::checkpoint::Checkpoint {
        crate::checkpoint::capture(&mut self.world)
    }

    /// A simulation of `scene` that continues from `saved`, a checkpoint of the same scene: the
    /// frames it computes are the uninterrupted run's, bit for bit.
    pub fn resume(
        scene: &BuiltScene,
        saved: &crate::checkpoint::Checkpoint,
    ) -> Result<Self, crate::checkpoint::RestoreError> {
        let mut sim = Simulation::new(scene);
        crate::checkpoint::restore(&mut sim.world, saved)?;
        Ok(sim)
    }

    /// Why the simulation failed, if it did.
    pub fn failure(&self) -> Option<Failure> {
        self.world.resource::<SimFailure>().0.clone()
    }
}
