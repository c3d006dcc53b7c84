//! The viewer layout sent with every recording and live stream: per patch a tab with a 3D view of
//! its own layers only, its eye set from the patch's rest bounds, over tabs of its energy (J),
//! log10 residual, Newton iterations and, with anchors, the anchor jumps (m); first, per shared
//! body, a 3D view of the body with every patch on it; beside them one plot of the stage timings
//! the scene runs (from frame 2: frame 1's set-up would flatten the rest), the colour legend,
//! the anchors' legend where there are anchors, the colour bar, and for remeshed layers their
//! material-space view.
//!
//! Written as blueprint archetypes directly, not through the SDK's `Blueprint` builder: in Rerun
//! 0.36 that builder cannot set a view's properties (`View::add_property` is crate-private), and
//! the eye and the plot legends are properties. The ids are numbered in the tree's order, so the
//! same scene sends the same blueprint.

use glam::DVec3;
use rerun::blueprint::components::{
    AutoViews, ColumnShare, ContainerKind, IncludedContent, QueryExpression, RootContainer, RowShare, ViewClass,
};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, EyeControls3D, PlotLegend, ViewBlueprint, ViewContents, ViewportBlueprint,
};
use rerun::{AsComponents, RecordingStream, RecordingStreamResult, SerializedComponentBatch};
use skinsim::scene::built::{BuiltPatch, LayerMesh};
use skinsim::scene::BuiltScene;

/// The per-patch plots: (the entity under /stats/<patch>, the plot's title).
pub const PATCH_PLOTS: [(&str, &str); 3] = [
    ("energy", "energy (J)"),
    ("log10_residual", "log10 residual (relative)"),
    ("newton_iterations", "Newton iterations"),
];

/// How far the eye stands from a patch's centre, in radii of its bounding sphere: Rerun's 3D
/// view opens about 50 degrees, which a sphere fills from 1 / sin(25°) = 2.4 radii.
const EYE_DISTANCE: f64 = 2.6;

/// The entity of the stage timings' colour key (a text document).
pub const TIMINGS_KEY: &str = "timings_key";

/// The stage timings' line colours, named for their key; a thirteenth stage starts over.
const STAGE_COLOURS: [(u32, &str); 12] = [
    (0x4c9be8ff, "blue"),
    (0xff8c1aff, "orange"),
    (0x3cb83cff, "green"),
    (0xe8483cff, "red"),
    (0xa57be0ff, "violet"),
    (0xb07a5aff, "brown"),
    (0xf08ad0ff, "pink"),
    (0xa0a0a0ff, "grey"),
    (0xd4d42aff, "olive"),
    (0x2ad4e0ff, "cyan"),
    (0xffffffff, "white"),
    (0xffd700ff, "gold"),
];

/// Logs each stage's line colour and name (static) and their key, a text document beside the
/// timings plot.
pub fn log_stage_colours(rec: &RecordingStream, stages: &[String]) -> RecordingStreamResult<()> {
    let mut key = Vec::new();
    for (s, (rgba, name)) in stages.iter().zip(STAGE_COLOURS.iter().cycle()) {
        let lines = rerun::SeriesLines::new().with_colors([rerun::Color::from_u32(*rgba)]).with_names([s.as_str()]);
        rec.log_static(format!("timings/{s}"), &lines)?;
        key.push(format!("{s} **{name}**"));
    }
    rec.log_static(TIMINGS_KEY, &rerun::TextDocument::from_markdown(key.join(" · ")))
}

/// One view: its class ("3D", "2D", "TimeSeries", "TextDocument"), name, origin, content
/// queries and properties (archetypes under the view's blueprint path, e.g. its eye).
pub struct View {
    pub class: &'static str,
    pub name: String,
    pub origin: String,
    pub contents: Vec<String>,
    pub properties: Vec<(&'static str, Vec<SerializedComponentBatch>)>,
}

/// A node of the layout: a view, or a container of nodes (`shares`: the column shares of a
/// horizontal container, the row shares of a vertical one).
pub enum Node {
    View(View),
    Container { kind: ContainerKind, name: Option<String>, children: Vec<Node>, shares: Option<Vec<f32>> },
}

impl View {
    fn new(class: &'static str, name: impl Into<String>, origin: impl Into<String>) -> Self {
        View {
            class,
            name: name.into(),
            origin: origin.into(),
            contents: vec!["$origin/**".into()],
            properties: vec![],
        }
    }
    fn with_contents(mut self, contents: impl IntoIterator<Item = String>) -> Self {
        self.contents = contents.into_iter().collect();
        self
    }
    fn with_property(mut self, name: &'static str, archetype: &dyn AsComponents) -> Self {
        self.properties.push((name, archetype.as_serialized_batches()));
        self
    }
    /// A time series of one quantity: its title names it, so no legend covers the data.
    fn plot(name: impl Into<String>, origin: impl Into<String>) -> Self {
        View::new("TimeSeries", name, origin).with_property("PlotLegend", &PlotLegend::new().with_visible(false))
    }
}

impl From<View> for Node {
    fn from(v: View) -> Self {
        Node::View(v)
    }
}

fn container(kind: ContainerKind, children: Vec<Node>, shares: Option<Vec<f32>>) -> Node {
    Node::Container { kind, name: None, children, shares }
}

fn named(name: &str, kind: ContainerKind, children: Vec<Node>, shares: Option<Vec<f32>>) -> Node {
    Node::Container { kind, name: Some(name.to_owned()), children, shares }
}

/// The layout for `scene`; `stages`: the keys of the stages that ran (a stage that never runs
/// gets no plot).
pub fn layout(scene: &BuiltScene, stages: &[String]) -> Node {
    // A shared body's tab: the body and every patch on it, as the character is seen.
    let bodies = scene.bodies.iter().enumerate().map(|(bi, b)| {
        let on: Vec<String> = std::iter::once(&b.name)
            .chain(scene.patches.iter().filter(|p| p.body == Some(bi)).map(|p| &p.name))
            .map(|n| format!("+ /patches/{n}/**"))
            .collect();
        let view = View::new("3D", b.name.clone(), "/patches").with_contents(on);
        Node::View(with_eye(view, b, false))
    });
    let patches: Vec<Node> = bodies
        .chain(scene.patches.iter().map(|p| {
            let view = with_eye(View::new("3D", p.name.clone(), format!("/patches/{}", p.name)), p, true);
            let mut plots: Vec<Node> = PATCH_PLOTS
                .iter()
                .map(|(entity, title)| {
                    View::plot(format!("{} {title}", p.name), format!("/stats/{}/{entity}", p.name)).into()
                })
                .collect();
            if p.anchors.is_some() {
                let origin = format!("/stats/{}/anchors", p.name);
                plots.push(View::plot(format!("{} anchor jumps (m)", p.name), origin).into());
            }
            let tabs = container(ContainerKind::Tabs, plots, None);
            named(&p.name, ContainerKind::Vertical, vec![view.into(), tabs], Some(vec![3.0, 1.4]))
        }))
        .collect();
    // The stage timings: several series, keyed by colour in a document under the plot (an
    // in-plot legend covers the data in every corner: the solve's line runs along the top, the
    // small stages along the bottom).
    let timings = View::plot("stage timings (ms), from frame 2", "/timings")
        .with_contents(stages.iter().map(|s| format!("+ /timings/{s}")));
    let key = View::new("TextDocument", "stage colours", format!("/{TIMINGS_KEY}"));
    let legend = View::new("TextDocument", "colour legend", format!("/{}", skinsim_systems::log::LEGEND));
    let bar = View::new(
        "2D",
        "colour bar: red -scale, white 0, blue +scale (the legend gives the scale)",
        format!("/{}", skinsim_systems::log::COLOUR_BAR),
    );
    let mut side: Vec<Node> = vec![timings.into(), key.into(), legend.into(), bar.into()];
    for p in scene.patches.iter().filter(|p| p.anchors.is_some()) {
        let skin = &p.layers[p.anchors.as_ref().expect("filtered").skin].name;
        let origin = format!("/{}/{}/{skin}", skinsim_systems::log_anchors::ANCHOR_LEGEND, p.name);
        side.push(View::new("TextDocument", format!("{} anchors", p.name), origin).into());
    }
    for p in &scene.patches {
        for l in p.layers.iter().filter(|l| l.remesh.is_some()) {
            let origin = format!("/material/{}/{}", p.name, l.name);
            side.push(View::new("3D", format!("{} {} material space", p.name, l.name), origin).into());
        }
    }
    let tabs = container(ContainerKind::Tabs, patches, None);
    // The timings plot gets twice a document's height, its key and the colour bar a strip.
    let shares = (0..side.len()).map(|i| [2.0, 0.6, 1.0, 0.4].get(i).copied().unwrap_or(1.0)).collect();
    let side = container(ContainerKind::Vertical, side, Some(shares));
    container(ContainerKind::Horizontal, vec![tabs, side], Some(vec![2.0, 1.0]))
}

/// `view` with its eye on `p`'s rest bounds. `own`: the view shows only the patch's own layers
/// (a patch's copy of its body, `layers[0]` when it sits on one, is left out of the bounds).
fn with_eye(view: View, p: &BuiltPatch, own: bool) -> View {
    let skip = usize::from(own && p.body.is_some());
    let layers = p.layers.iter().skip(skip);
    let mut points = Vec::new();
    let mut tris = Vec::new();
    for l in layers {
        let offset = points.len() as u32;
        points.extend_from_slice(l.mesh.rest());
        if let LayerMesh::Surface(m) = &l.mesh {
            tris.extend(m.faces.iter().map(|f| f.map(|i| i + offset)));
        }
    }
    match eye(&points, &tris) {
        Some((position, target, up)) => {
            let f3 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32];
            let eye = EyeControls3D::new().with_position(f3(position)).with_look_target(f3(target)).with_eye_up(f3(up));
            view.with_property("EyeControls3D", &eye)
        }
        None => view,
    }
}

/// The eye that frames `points`: (position, look target, up). It looks at the bounding box's
/// centre along the surface's area-weighted mean normal (the side a patch's skin faces), or,
/// where that nearly cancels (a sleeve round a finger), along the bounding box's thinnest axis;
/// from `EYE_DISTANCE` bounding radii; up is the engine's +Z unless the eye looks along it.
pub fn eye(points: &[DVec3], tris: &[[u32; 3]]) -> Option<(DVec3, DVec3, DVec3)> {
    if points.is_empty() {
        return None;
    }
    let (lo, hi) = points.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    let centre = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    if radius <= 0.0 {
        return None;
    }
    // (the area-weighted normal and the area, in one pass over the triangles)
    let (area_normal, area) = tris.iter().fold((DVec3::ZERO, 0.0), |(n, a), t| {
        let [p, q, r] = t.map(|i| points[i as usize]);
        let half = 0.5 * (q - p).cross(r - p);
        (n + half, a + half.length())
    });
    let dir = if area > 0.0 && area_normal.length() > 0.3 * area { area_normal.normalize() } else { thinnest(lo, hi) };
    let up = if dir.z.abs() > 0.9 { DVec3::Y } else { DVec3::Z };
    Some((centre + EYE_DISTANCE * radius * dir, centre, up))
}

/// The bounding box's thinnest axis, as seen from its positive side.
fn thinnest(lo: DVec3, hi: DVec3) -> DVec3 {
    let e = hi - lo;
    if e.z <= e.x && e.z <= e.y {
        DVec3::Z
    } else if e.y <= e.x {
        DVec3::Y
    } else {
        DVec3::X
    }
}

impl Node {
    /// Sends the layout to `rec` as its active and default blueprint.
    pub fn send(&self, rec: &RecordingStream) -> RecordingStreamResult<()> {
        let app = rec.store_info().map(|i| i.application_id().clone()).unwrap_or_else(|| "skinsim".into());
        let (bp, storage) = rerun::RecordingStreamBuilder::new(app).blueprint().memory()?;
        bp.set_time_sequence("blueprint", 0);
        let mut next = 0;
        let root = self.log(&bp, &mut next)?;
        let root_id = RootContainer(rerun::datatypes::Uuid { bytes: id_bytes(root.1) });
        bp.log(
            "viewport",
            &ViewportBlueprint::new().with_root_container(root_id).with_auto_views(AutoViews(false.into())),
        )?;
        bp.flush_blocking().ok();
        let msgs = storage.take();
        let store = msgs.iter().find_map(|m| match m {
            rerun::log::LogMsg::SetStoreInfo(info) => Some(info.info.store_id.clone()),
            _ => None,
        });
        if let Some(blueprint_id) = store {
            let activate = rerun::external::re_log_types::BlueprintActivationCommand {
                blueprint_id,
                make_active: true,
                make_default: true,
            };
            rec.send_blueprint(msgs, activate);
        }
        Ok(())
    }

    /// Logs the node (children first) and returns its blueprint path and number.
    fn log(&self, bp: &RecordingStream, next: &mut u64) -> RecordingStreamResult<(String, u64)> {
        match self {
            Node::View(v) => {
                let n = take(next);
                let path = format!("view/{}", id_text(n));
                bp.log(
                    format!("{path}/ViewContents"),
                    &ViewContents::new(v.contents.iter().map(|q| QueryExpression(q.clone().into()))),
                )?;
                let arch = ViewBlueprint::new(ViewClass(v.class.into()))
                    .with_display_name(v.name.clone())
                    .with_space_origin(v.origin.clone());
                bp.log(path.clone(), &arch)?;
                for (name, batches) in &v.properties {
                    bp.log_serialized_batches(format!("{path}/{name}"), false, batches.iter().cloned())?;
                }
                Ok((path, n))
            }
            Node::Container { kind, name, children, shares } => {
                let contents = children.iter().map(|c| c.log(bp, next).map(|(p, _)| IncludedContent(p.into())));
                let contents = contents.collect::<RecordingStreamResult<Vec<_>>>()?;
                let n = take(next);
                let path = format!("container/{}", id_text(n));
                let mut arch = ContainerBlueprint::new(*kind).with_contents(contents);
                if let Some(name) = name {
                    arch = arch.with_display_name(name.clone());
                }
                match (kind, shares) {
                    (ContainerKind::Horizontal, Some(s)) => {
                        arch = arch.with_col_shares(s.iter().map(|x| ColumnShare((*x).into())))
                    }
                    (ContainerKind::Vertical, Some(s)) => {
                        arch = arch.with_row_shares(s.iter().map(|x| RowShare((*x).into())))
                    }
                    _ => {}
                }
                bp.log(path.clone(), &arch)?;
                Ok((path, n))
            }
        }
    }

    /// Every view in the tree, depth first.
    pub fn views(&self) -> Vec<&View> {
        match self {
            Node::View(v) => vec![v],
            Node::Container { children, .. } => children.iter().flat_map(Node::views).collect(),
        }
    }
}

fn take(next: &mut u64) -> u64 {
    *next += 1;
    *next
}

/// The `n`th id of the layout: a version-4-shaped UUID with `n` in its last 48 bits.
fn id_bytes(n: u64) -> [u8; 16] {
    let mut b = [0x5c, 0x1a, 0x5c, 0x1a, 0, 0, 0x40, 0, 0x80, 0, 0, 0, 0, 0, 0, 0];
    b[10..].copy_from_slice(&n.to_be_bytes()[2..]);
    b
}

fn id_text(n: u64) -> String {
    let h: String = id_bytes(n).iter().map(|x| format!("{x:02x}")).collect();
    format!("{}-{}-{}-{}-{}", &h[0..8], &h[8..12], &h[12..16], &h[16..20], &h[20..32])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_uuids_in_order() {
        assert_eq!(id_text(1), "5c1a5c1a-0000-4000-8000-000000000001");
        assert_eq!(id_text(0x1_0000_0000), "5c1a5c1a-0000-4000-8000-000100000000");
    }

    #[test]
    fn the_eye_faces_a_flat_patch_and_sees_all_of_it() {
        // A 40 x 20 mm patch in the plane z = 0.1, facing +Z: the eye stands above it.
        let points = [
            DVec3::new(0.0, 0.0, 0.1),
            DVec3::new(0.04, 0.0, 0.1),
            DVec3::new(0.04, 0.02, 0.1),
            DVec3::new(0.0, 0.02, 0.1),
        ];
        let (pos, target, up) = eye(&points, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        assert!((target - DVec3::new(0.02, 0.01, 0.1)).length() < 1e-12);
        let d = pos - target;
        assert!(d.normalize().dot(DVec3::Z) > 0.999, "{d}");
        assert_eq!(up, DVec3::Y, "looking down +Z, up is +Y");
        // Every corner within 25 degrees of the line of sight.
        for p in points {
            let to = (p - pos).normalize();
            assert!(to.dot(-d.normalize()) > 25f64.to_radians().cos(), "{p}");
        }
        // Turned over, the eye goes below.
        let (pos, ..) = eye(&points, &[[0, 2, 1], [0, 3, 2]]).unwrap();
        assert!(pos.z < 0.1);
    }

    #[test]
    fn a_sleeve_is_seen_across_its_axis() {
        // A closed tube along X: its normals cancel; the eye looks across the tube, not down it.
        let n = 16;
        let mut points = vec![];
        for i in 0..2 {
            for k in 0..n {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                points.push(DVec3::new(0.05 * i as f64, 0.01 * a.cos(), 0.008 * a.sin()));
            }
        }
        let mut tris = vec![];
        for k in 0..n as u32 {
            let j = (k + 1) % n as u32;
            tris.push([k, j, n as u32 + j]);
            tris.push([k, n as u32 + j, n as u32 + k]);
        }
        let (pos, target, up) = eye(&points, &tris).unwrap();
        let d = (pos - target).normalize();
        assert!(d.x.abs() < 1e-9, "{d}");
        assert!(d.z > 0.999, "the thinner side (0.8 cm) faces the eye, from +Z: {d}");
        assert_eq!(up, DVec3::Y);
    }
}
