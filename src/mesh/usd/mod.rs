//! A USD cache of the layers' meshes: one stage, in Pixar's crate (binary) format by default
//! (`.usdc`, written by the `openusd` crate) or as text (`.usda`). Per patch an Xform, per layer
//! a Mesh prim named `<patch>_<layer>` (unique in the stage, so a DCC that names its objects
//! after the mesh prims keeps them apart), with its topology once (or time-sampled when it is
//! remeshed), its points, normals and extent sampled at every frame, the rest state as frame 0,
//! and `st`: the asset's own UVs (a character's atlas, an OBJ body's `vt`), else the material
//! coordinates in the scene's length unit. Frames are spooled to disk as they come (no frame is
//! held in memory), and the stage is written from the spool when the run ends.

mod binary;
mod spool;
mod text;

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};

use spool::{SpoolReader, SpoolWriter};

/// One frame of one layer.
pub struct LayerFrame<'a> {
    pub positions: &'a [DVec3],
    pub normals: &'a [DVec3],
    /// `st`, in the asset's UV units (`UsdStage::st_unit` converts material coordinates).
    pub uv: &'a [DVec2],
    pub tris: &'a [[u32; 3]],
    /// The triangles (and so the vertex count) differ from the previous frame's.
    pub new_topology: bool,
    /// `uv` is a character asset's own UV layout (issue 62), not material coordinates: the prim
    /// says so (`customData` `st = "asset"`).
    pub asset_uv: bool,
}

/// The stage's file format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UsdFormat {
    /// Pixar's crate format (`.usdc`): about a quarter of the text's size, read many times faster.
    #[default]
    Crate,
    /// The text format (`.usda`), for reading and diffing.
    Text,
}

impl UsdFormat {
    /// The stage's file name in the output folder.
    pub fn file_name(self) -> &'static str {
        match self {
            UsdFormat::Crate => "skinsim.usdc",
            UsdFormat::Text => "skinsim.usda",
        }
    }
}

/// How the stage is written.
#[derive(Clone, Copy, Debug)]
pub struct UsdOptions {
    pub format: UsdFormat,
    /// `doubleSided` on every mesh (a DCC then draws both sides of the skin).
    pub double_sided: bool,
    /// Metres per unit of `st` where a layer has no asset UVs: its material coordinates are
    /// written in the scene's length unit, as an OBJ asset's `vt` are.
    pub st_unit: f64,
}

impl Default for UsdOptions {
    fn default() -> Self {
        UsdOptions { format: UsdFormat::Crate, double_sided: false, st_unit: 1.0 }
    }
}

/// Where a stage stood after a frame (a checkpoint's): its prims and each spool's length. A
/// resumed run reopens the spool cut back to it (`UsdStage::reopen`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UsdMark {
    frames: Option<(u32, u32)>,
    prims: Vec<PrimMark>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct PrimMark {
    patch: String,
    layer: String,
    names: (String, String),
    varying: bool,
    sampled_topology: bool,
    fixed: Option<(Vec<[u32; 3]>, Vec<DVec2>)>,
    asset_uv: bool,
    spools: Vec<u64>,
}

/// The stage being built.
pub struct UsdStage {
    path: PathBuf,
    spool: PathBuf,
    doc: String,
    frames_per_second: f64,
    frames: Option<(u32, u32)>,
    prims: Vec<Prim>,
    options: UsdOptions,
}

struct Prim {
    patch: String,
    layer: String,
    /// Prim names: the patch's Xform, the layer's Mesh (`<patch>_<layer>`, unique in the stage).
    names: (String, String),
    /// Remeshed: topology and `st` are time-sampled too (from the first frame on).
    varying: bool,
    sampled_topology: bool,
    /// One spool per time-sampled attribute, in `ATTRIBUTES` order.
    spools: Vec<SpoolWriter>,
    /// The topology and `st` of a layer whose topology never changes.
    fixed: Option<(Vec<[u32; 3]>, Vec<DVec2>)>,
    /// `st` holds the asset's UVs (customData `st = "asset"`); else the material coordinates in
    /// the scene's length unit (`st = "material"`, `stMetres`: metres per unit).
    asset_uv: bool,
}

/// A time-sampled attribute of a Mesh prim.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Attr {
    Points,
    Normals,
    Extent,
    Counts,
    Indices,
    St,
}

/// The time-sampled attributes; the last three only on a remeshed layer.
const ATTRIBUTES: [Attr; 6] = [Attr::Points, Attr::Normals, Attr::Extent, Attr::Counts, Attr::Indices, Attr::St];

impl Attr {
    /// (USD type, attribute name, spool file name)
    fn names(self) -> (&'static str, &'static str, &'static str) {
        match self {
            Attr::Points => ("point3f[]", "points", "points"),
            Attr::Normals => ("normal3f[]", "normals", "normals"),
            Attr::Extent => ("float3[]", "extent", "extent"),
            Attr::Counts => ("int[]", "faceVertexCounts", "counts"),
            Attr::Indices => ("int[]", "faceVertexIndices", "indices"),
            Attr::St => ("texCoord2f[]", "primvars:st", "st"),
        }
    }

    fn is_int(self) -> bool {
        matches!(self, Attr::Counts | Attr::Indices)
    }

    /// Per-vertex interpolation (normals and st).
    fn per_vertex(self) -> bool {
        matches!(self, Attr::Normals | Attr::St)
    }
}

impl UsdStage {
    /// A stage to be written to `dir`/`options.format.file_name()`; its spool lives in a hidden
    /// folder beside it. `doc`: the stage's documentation string; `frames_per_second`: the time
    /// codes per second (a frame is one time code).
    pub fn new(dir: &Path, doc: &str, frames_per_second: f64, options: UsdOptions) -> std::io::Result<Self> {
        let path = dir.join(options.format.file_name());
        let spool = dir.join(format!(".{}.spool", options.format.file_name()));
        if spool.exists() {
            std::fs::remove_dir_all(&spool)?;
        }
        std::fs::create_dir_all(&spool)?;
        Ok(UsdStage { path, spool, doc: doc.to_string(), frames_per_second, frames: None, prims: Vec::new(), options })
    }

    /// The stage's spool after the frames added so far, flushed, and its mark.
    pub fn mark(&mut self) -> std::io::Result<UsdMark> {
        let mut prims = Vec::with_capacity(self.prims.len());
        for p in &mut self.prims {
            for s in &mut p.spools {
                s.flush()?;
            }
            prims.push(PrimMark {
                patch: p.patch.clone(),
                layer: p.layer.clone(),
                names: p.names.clone(),
                varying: p.varying,
                sampled_topology: p.sampled_topology,
                fixed: p.fixed.clone(),
                asset_uv: p.asset_uv,
                spools: p.spools.iter().map(|s| s.len()).collect(),
            });
        }
        Ok(UsdMark { frames: self.frames, prims })
    }

    /// The stage of an interrupted run, continued from `mark`: its spool (which `finish_keeping`
    /// or a killed run left in `dir`) cut back to the mark.
    pub fn reopen(
        dir: &Path,
        doc: &str,
        frames_per_second: f64,
        options: UsdOptions,
        mark: &UsdMark,
    ) -> std::io::Result<Self> {
        let path = dir.join(options.format.file_name());
        let spool = dir.join(format!(".{}.spool", options.format.file_name()));
        let mut prims = Vec::with_capacity(mark.prims.len());
        for (i, m) in mark.prims.iter().enumerate() {
            let spools = m
                .spools
                .iter()
                .enumerate()
                .map(|(k, &len)| SpoolWriter::reopen(&spool.join(format!("{i}.{}", ATTRIBUTES[k].names().2)), len))
                .collect::<std::io::Result<_>>()?;
            prims.push(Prim {
                patch: m.patch.clone(),
                layer: m.layer.clone(),
                names: m.names.clone(),
                varying: m.varying,
                sampled_topology: m.sampled_topology,
                spools,
                fixed: m.fixed.clone(),
                asset_uv: m.asset_uv,
            });
        }
        Ok(UsdStage { path, spool, doc: doc.to_string(), frames_per_second, frames: mark.frames, prims, options })
    }

    /// Metres per unit of `st` for material coordinates (`UsdOptions::st_unit`).
    pub fn st_unit(&self) -> f64 {
        self.options.st_unit
    }

    /// A layer's `st`: the asset's own UVs where every vertex has them (a character's; true),
    /// else its material coordinates `uv` (m) in the scene's length unit (an OBJ body's `vt`).
    pub fn st(&self, asset: Option<Vec<DVec2>>, uv: &[DVec2]) -> (bool, Vec<DVec2>) {
        match asset {
            Some(st) => (true, st),
            None => (false, uv.iter().map(|u| *u / self.options.st_unit).collect()),
        }
    }

    /// The stage's path (written by `finish`).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Adds `frame` of layer `layer` of patch `patch`; `remeshed`: its topology may change.
    pub fn add(&mut self, patch: &str, layer: &str, remeshed: bool, frame: u32, f: &LayerFrame) -> std::io::Result<()> {
        self.frames = Some(self.frames.map_or((frame, frame), |(a, b)| (a.min(frame), b.max(frame))));
        let at = match self.prims.iter().position(|p| p.patch == patch && p.layer == layer) {
            Some(i) => i,
            None => self.open_prim(patch, layer, remeshed)?,
        };
        let prim = &mut self.prims[at];
        prim.asset_uv |= f.asset_uv;
        let w = &mut prim.spools;
        let xyz = |v: &[DVec3]| v.iter().flat_map(|p| [p.x as f32, p.y as f32, p.z as f32]).collect::<Vec<f32>>();
        w[0].floats(frame, xyz(f.positions).into_iter())?;
        w[1].floats(frame, xyz(f.normals).into_iter())?;
        let extent =
            f.positions.iter().fold([DVec3::INFINITY, DVec3::NEG_INFINITY], |[lo, hi], p| [lo.min(*p), hi.max(*p)]);
        w[2].floats(frame, xyz(&extent).into_iter())?;
        if prim.varying {
            if f.new_topology || !prim.sampled_topology {
                w[3].ints(frame, f.tris.iter().map(|_| 3))?;
                w[4].ints(frame, f.tris.iter().flat_map(|t| t.map(|v| v as i32)).collect::<Vec<_>>().into_iter())?;
                w[5].floats(frame, f.uv.iter().flat_map(|t| [t.x as f32, t.y as f32]).collect::<Vec<_>>().into_iter())?;
                prim.sampled_topology = true;
            }
        } else if prim.fixed.is_none() {
            prim.fixed = Some((f.tris.to_vec(), f.uv.to_vec()));
        }
        Ok(())
    }

    fn open_prim(&mut self, patch: &str, layer: &str, remeshed: bool) -> std::io::Result<usize> {
        let patch_name = match self.prims.iter().find(|p| p.patch == patch) {
            Some(p) => p.names.0.clone(),
            None => unique(prim_name(patch), self.prims.iter().map(|p| &p.names.0)),
        };
        // Mesh names unique in the whole stage (and apart from the Xforms'), so that a DCC
        // naming its objects after the mesh prims keeps every patch's layers apart.
        let taken: Vec<String> = self.prims.iter().flat_map(|p| [p.names.0.clone(), p.names.1.clone()]).collect();
        let layer_name = unique(prim_name(&format!("{patch_name}_{layer}")), taken.iter().chain([&patch_name]));
        let i = self.prims.len();
        let count = if remeshed { ATTRIBUTES.len() } else { 3 };
        let spools = (0..count)
            .map(|k| SpoolWriter::create(&self.spool.join(format!("{i}.{}", ATTRIBUTES[k].names().2))))
            .collect::<std::io::Result<_>>()?;
        self.prims.push(Prim {
            patch: patch.to_string(),
            layer: layer.to_string(),
            names: (patch_name, layer_name),
            varying: remeshed,
            sampled_topology: false,
            spools,
            fixed: None,
            asset_uv: false,
        });
        Ok(i)
    }

    /// The patches in the order first added, each with its prims (index, prim).
    fn patches(&self) -> Vec<(&str, Vec<(usize, &Prim)>)> {
        let mut out: Vec<(&str, Vec<(usize, &Prim)>)> = Vec::new();
        for (i, p) in self.prims.iter().enumerate() {
            match out.iter_mut().find(|(name, _)| *name == p.patch) {
                Some((_, list)) => list.push((i, p)),
                None => out.push((&p.patch, vec![(i, p)])),
            }
        }
        out
    }

    /// A reader of prim `i`'s spooled attribute `a`.
    fn reader(&self, i: usize, a: Attr) -> std::io::Result<SpoolReader> {
        SpoolReader::open(&self.spool.join(format!("{i}.{}", a.names().2)))
    }

    /// Writes the stage (every frame added so far) and removes the spool; returns its path.
    pub fn finish(self) -> std::io::Result<PathBuf> {
        self.write(false)
    }

    /// Writes the stage and keeps the spool, for a run that may be resumed (`reopen`).
    pub fn finish_keeping(self) -> std::io::Result<PathBuf> {
        self.write(true)
    }

    fn write(mut self, keep: bool) -> std::io::Result<PathBuf> {
        for p in &mut self.prims {
            for s in &mut p.spools {
                s.flush()?;
            }
        }
        let ext = self.path.extension().and_then(|e| e.to_str()).unwrap_or("usd");
        let partial = self.path.with_extension(format!("{ext}.partial"));
        match self.options.format {
            UsdFormat::Text => text::write(&self, &partial)?,
            UsdFormat::Crate => binary::write(&self, &partial)?,
        }
        std::fs::rename(&partial, &self.path)?;
        if !keep {
            std::fs::remove_dir_all(&self.spool)?;
        }
        Ok(self.path)
    }
}

/// A USD prim name for a scene name: letters, digits and '_', not starting with a digit.
fn prim_name(name: &str) -> String {
    let mut s: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    if !s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        s.insert(0, '_');
    }
    s
}

/// `name`, or `name_2`, `name_3`... the first that is not `taken`.
fn unique<'a>(name: String, taken: impl Iterator<Item = &'a String> + Clone) -> String {
    let free = |n: &String| !taken.clone().any(|t| t == n);
    if free(&name) {
        return name;
    }
    (2..).map(|k| format!("{name}_{k}")).find(|n| free(n)).expect("some suffix is free")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_names_are_identifiers_and_unique() {
        assert_eq!(prim_name("skin"), "skin");
        assert_eq!(prim_name("knuckle-1.left"), "knuckle_1_left");
        assert_eq!(prim_name("2nd"), "_2nd");
        let taken = ["a_b".to_string()];
        assert_eq!(unique(prim_name("a-b"), taken.iter()), "a_b_2");
    }

    /// Three frames (0-2) of two patches that both have a layer "skin".
    fn stage(dir: &Path, format: UsdFormat) -> PathBuf {
        std::fs::create_dir_all(dir).unwrap();
        let options = UsdOptions { format, double_sided: true, st_unit: 1e-3 };
        let mut stage = UsdStage::new(dir, "test", 30.0, options).unwrap();
        let tris = [[0, 1, 2]];
        let uv = [DVec2::ZERO, DVec2::X, DVec2::Y];
        for frame in 0..=2 {
            for patch in ["patch-1", "patch 2"] {
                let p = [DVec3::ZERO, DVec3::X, DVec3::Y * (frame + 1) as f64];
                let n = [DVec3::Z; 3];
                let f = LayerFrame {
                    positions: &p,
                    normals: &n,
                    uv: &uv,
                    tris: &tris,
                    new_topology: frame == 0,
                    asset_uv: false,
                };
                stage.add(patch, "skin", false, frame, &f).unwrap();
            }
        }
        stage.finish().unwrap()
    }

    #[test]
    fn a_text_stage_holds_every_frame_and_leaves_no_spool() {
        let dir = std::env::temp_dir().join(format!("skinsim-usda-{}", std::process::id()));
        let written = stage(&dir, UsdFormat::Text);
        assert_eq!(written.file_name().unwrap(), "skinsim.usda");
        let text = std::fs::read_to_string(&written).unwrap();
        assert!(text.starts_with("#usda 1.0"));
        assert!(text.contains("def Xform \"patch_1\"") && text.contains("def Mesh \"patch_1_skin\""));
        assert!(text.contains("def Xform \"patch_2\"") && text.contains("def Mesh \"patch_2_skin\""));
        assert!(text.contains("startTimeCode = 0") && text.contains("endTimeCode = 2"));
        assert!(text.contains("2: [(0, 0, 0), (1, 0, 0), (0, 3, 0)],"), "{text}");
        assert!(text.contains("int[] faceVertexIndices = [0, 1, 2]\n"), "{text}");
        assert!(text.contains("uniform bool doubleSided = 1"), "{text}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "only the stage is left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_crate_stage_reads_back_with_its_samples_names_and_metadata() {
        use openusd::sdf::{Layer, Value};
        let dir = std::env::temp_dir().join(format!("skinsim-usdc-{}", std::process::id()));
        let written = stage(&dir, UsdFormat::Crate);
        assert_eq!(written.file_name().unwrap(), "skinsim.usdc");
        assert_eq!(&std::fs::read(&written).unwrap()[..8], b"PXR-USDC");
        let layer = Layer::open(written.to_str().unwrap()).unwrap();
        assert_eq!((layer.start_time_code(), layer.end_time_code()), (0.0, 2.0));
        assert_eq!(layer.time_codes_per_second(), 30.0);
        for mesh in ["/skinsim/patch_1/patch_1_skin", "/skinsim/patch_2/patch_2_skin"] {
            let points = layer.attribute(format!("{mesh}.points").as_str()).unwrap().expect(mesh);
            let samples = points.time_samples().expect("points are time-sampled");
            assert_eq!(samples.len(), 3);
            let Value::Vec3fVec(last) = &samples[2].1 else { panic!("{:?}", samples[2].1) };
            assert_eq!(<[f32; 3]>::from(last[2]), [0.0, 3.0, 0.0]);
            let sided = layer.attribute(format!("{mesh}.doubleSided").as_str()).unwrap().expect("doubleSided");
            assert_eq!(sided.get::<bool>("default"), Some(true));
        }
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "only the stage is left");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
