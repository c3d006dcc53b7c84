//! A USD cache of the layers' meshes, as one text stage (`.usda`, Pixar's documented format):
//! per layer a Mesh prim with its topology once (or time-sampled when it is remeshed), its
//! points, normals and extent sampled at every frame, and its material coordinates as the `st`
//! primvar. Frames are spooled to disk as they come (no frame is held in memory), and the stage
//! is written from the spool when the run ends.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};

/// One frame of one layer.
pub struct LayerFrame<'a> {
    pub positions: &'a [DVec3],
    pub normals: &'a [DVec3],
    pub uv: &'a [DVec2],
    pub tris: &'a [[u32; 3]],
    /// The triangles (and so the vertex count) differ from the previous frame's.
    pub new_topology: bool,
    /// `uv` is a character asset's own UV layout (issue 62), not material coordinates: the prim
    /// says so (`customData` `st = "asset"`).
    pub asset_uv: bool,
}

/// The stage being built.
pub struct UsdStage {
    path: PathBuf,
    spool: PathBuf,
    doc: String,
    frames_per_second: f64,
    frames: Option<(u32, u32)>,
    prims: Vec<Prim>,
}

struct Prim {
    patch: String,
    layer: String,
    /// Sanitized prim names (patch Xform, layer Mesh).
    names: (String, String),
    /// Remeshed: topology and `st` are time-sampled too (from the first frame on).
    varying: bool,
    sampled_topology: bool,
    /// One spool file per time-sampled attribute, in `ATTRIBUTES` order.
    spools: Vec<BufWriter<File>>,
    /// The topology and `st` of a layer whose topology never changes.
    fixed: Option<(Vec<[u32; 3]>, Vec<DVec2>)>,
    /// `st` holds the asset's UVs.
    asset_uv: bool,
}

/// The time-sampled attributes: (USD declaration, spool file name). The last three are sampled
/// only on a remeshed layer.
const ATTRIBUTES: [(&str, &str); 6] = [
    ("point3f[] points", "points"),
    ("normal3f[] normals", "normals"),
    ("float3[] extent", "extent"),
    ("int[] faceVertexCounts", "counts"),
    ("int[] faceVertexIndices", "indices"),
    ("texCoord2f[] primvars:st", "st"),
];

impl UsdStage {
    /// A stage to be written to `path`; its spool lives in a hidden folder beside it.
    /// `doc`: the stage's documentation string; `frames_per_second`: the time codes per second
    /// (a frame is one time code).
    pub fn new(path: &Path, doc: &str, frames_per_second: f64) -> std::io::Result<Self> {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("stage");
        let spool = path.with_file_name(format!(".{name}.spool"));
        if spool.exists() {
            std::fs::remove_dir_all(&spool)?;
        }
        std::fs::create_dir_all(&spool)?;
        Ok(UsdStage {
            path: path.to_path_buf(),
            spool,
            doc: doc.to_string(),
            frames_per_second,
            frames: None,
            prims: Vec::new(),
        })
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
        let f3 = |w: &mut BufWriter<File>, v: &DVec3| write!(w, "({}, {}, {})", v.x as f32, v.y as f32, v.z as f32);
        sample(&mut w[0], frame, f.positions, f3)?;
        sample(&mut w[1], frame, f.normals, f3)?;
        let extent =
            f.positions.iter().fold([DVec3::INFINITY, DVec3::NEG_INFINITY], |[lo, hi], p| [lo.min(*p), hi.max(*p)]);
        sample(&mut w[2], frame, &extent, f3)?;
        if prim.varying {
            if f.new_topology || !prim.sampled_topology {
                sample(&mut w[3], frame, f.tris, |w, _| write!(w, "3"))?;
                sample(&mut w[4], frame, f.tris, |w, t| write!(w, "{}, {}, {}", t[0], t[1], t[2]))?;
                sample(&mut w[5], frame, f.uv, |w, t| write!(w, "({}, {})", t.x as f32, t.y as f32))?;
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
        let siblings = self.prims.iter().filter(|p| p.patch == patch).map(|p| &p.names.1);
        let layer_name = unique(prim_name(layer), siblings);
        let i = self.prims.len();
        let count = if remeshed { ATTRIBUTES.len() } else { 3 };
        let spools = (0..count)
            .map(|k| File::create(self.spool.join(format!("{i}.{}", ATTRIBUTES[k].1))).map(BufWriter::new))
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

    /// Writes the stage (every frame added so far) and removes the spool; returns its path.
    pub fn finish(mut self) -> std::io::Result<PathBuf> {
        for p in &mut self.prims {
            for s in &mut p.spools {
                s.flush()?;
            }
        }
        let partial = self.path.with_extension("usda.partial");
        let mut w = BufWriter::new(File::create(&partial)?);
        let (first, last) = self.frames.unwrap_or((0, 0));
        writeln!(w, "#usda 1.0\n(")?;
        writeln!(w, "    defaultPrim = \"skinsim\"\n    doc = \"{}\"", escape(&self.doc))?;
        writeln!(w, "    metersPerUnit = 1\n    upAxis = \"Z\"")?;
        writeln!(w, "    startTimeCode = {first}\n    endTimeCode = {last}")?;
        writeln!(w, "    timeCodesPerSecond = {0}\n    framesPerSecond = {0}\n)\n", self.frames_per_second)?;
        writeln!(w, "def Xform \"skinsim\"\n{{")?;
        let mut patches: Vec<&str> = Vec::new();
        for p in &self.prims {
            if !patches.contains(&p.patch.as_str()) {
                patches.push(&p.patch);
            }
        }
        for patch in patches {
            let mut prims = self.prims.iter().enumerate().filter(|(_, p)| p.patch == patch).peekable();
            let name = &prims.peek().expect("a patch has a prim").1.names.0;
            writeln!(
                w,
                "    def Xform \"{name}\" (\n        customData = {{ string name = \"{}\" }}\n    )\n    {{",
                escape(patch)
            )?;
            for (i, prim) in prims {
                self.write_mesh(&mut w, i, prim)?;
            }
            writeln!(w, "    }}")?;
        }
        writeln!(w, "}}")?;
        w.flush()?;
        drop(w);
        std::fs::rename(&partial, &self.path)?;
        std::fs::remove_dir_all(&self.spool)?;
        Ok(self.path)
    }

    fn write_mesh(&self, w: &mut impl Write, i: usize, prim: &Prim) -> std::io::Result<()> {
        let name = &prim.names.1;
        writeln!(
            w,
            "        def Mesh \"{name}\" (\n            customData = {{ string name = \"{}\"{} }}\n        )\n        {{",
            escape(&prim.layer),
            if prim.asset_uv { "; string st = \"asset\"" } else { "" }
        )?;
        writeln!(w, "            uniform token orientation = \"rightHanded\"")?;
        writeln!(w, "            uniform token subdivisionScheme = \"none\"")?;
        writeln!(w, "            normal3f[] normals (\n                interpolation = \"vertex\"\n            )")?;
        match &prim.fixed {
            Some((tris, uv)) => {
                write!(w, "            int[] faceVertexCounts = [")?;
                list(w, tris, |w, _| write!(w, "3"))?;
                write!(w, "\n            int[] faceVertexIndices = [")?;
                list(w, tris, |w, t| write!(w, "{}, {}, {}", t[0], t[1], t[2]))?;
                write!(w, "\n            texCoord2f[] primvars:st = [")?;
                list(w, uv, |w, t| write!(w, "({}, {})", t.x as f32, t.y as f32))?;
                writeln!(w, " (\n                interpolation = \"vertex\"\n            )")?;
            }
            None => writeln!(
                w,
                "            texCoord2f[] primvars:st (\n                interpolation = \"vertex\"\n            )"
            )?,
        }
        for (decl, file) in ATTRIBUTES.iter().take(prim.spools.len()) {
            writeln!(w, "            {decl}.timeSamples = {{")?;
            std::io::copy(&mut File::open(self.spool.join(format!("{i}.{file}")))?, w)?;
            writeln!(w, "            }}")?;
        }
        writeln!(w, "        }}")
    }
}

/// Writes the items of `items` comma-separated, then "]".
fn list<T, W: Write>(
    w: &mut W,
    items: &[T],
    mut item: impl FnMut(&mut W, &T) -> std::io::Result<()>,
) -> std::io::Result<()> {
    for (i, x) in items.iter().enumerate() {
        if i > 0 {
            write!(w, ", ")?;
        }
        item(w, x)?;
    }
    write!(w, "]")
}

/// A time sample of a list: "        <frame>: [items],\n".
fn sample<T, W: Write>(
    w: &mut W,
    frame: u32,
    items: &[T],
    item: impl FnMut(&mut W, &T) -> std::io::Result<()>,
) -> std::io::Result<()> {
    write!(w, "        {frame}: [")?;
    list(w, items, item)?;
    writeln!(w, ",")
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

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
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

    #[test]
    fn a_stage_holds_every_frame_and_leaves_no_spool() {
        let dir = std::env::temp_dir().join(format!("skinsim-usd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.usda");
        let mut stage = UsdStage::new(&path, "test", 30.0).unwrap();
        let tris = [[0, 1, 2]];
        let uv = [DVec2::ZERO, DVec2::X, DVec2::Y];
        for frame in 1..=3 {
            let p = [DVec3::ZERO, DVec3::X, DVec3::Y * frame as f64];
            let n = [DVec3::Z; 3];
            let f = LayerFrame {
                positions: &p,
                normals: &n,
                uv: &uv,
                tris: &tris,
                new_topology: frame == 1,
                asset_uv: false,
            };
            stage.add("patch-1", "skin", false, frame, &f).unwrap();
        }
        let written = stage.finish().unwrap();
        let text = std::fs::read_to_string(&written).unwrap();
        assert!(text.starts_with("#usda 1.0"));
        assert!(text.contains("def Xform \"patch_1\"") && text.contains("def Mesh \"skin\""));
        assert!(text.contains("startTimeCode = 1") && text.contains("endTimeCode = 3"));
        assert!(text.contains("3: [(0, 0, 0), (1, 0, 0), (0, 3, 0)],"), "{text}");
        assert!(text.contains("int[] faceVertexIndices = [0, 1, 2]\n"), "{text}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "only the stage is left");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
