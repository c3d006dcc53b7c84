//! The shared dilatation of a cell of six tetrahedra (`physics::cell`): volume layers with
//! `VolumeElement::Cell` evaluate their lambda term once per cell.

use glam::DVec3;

use super::TetElem;
use crate::physics::cell::{self, CellRest, Dilatation, CELL_TETS, CELL_VERTS};
use crate::physics::psd::Filter;
use crate::solve::element::{gather, renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

#[derive(Clone, Copy, Debug)]
pub struct CellElem {
    pub v: [u32; CELL_VERTS],
    pub rest: CellRest,
}

impl CellElem {
    /// The cell of six tetrahedra over eight distinct vertices (their lambda terms, to be
    /// evaluated here instead); None for any other group.
    pub(crate) fn from_tets(tets: &[TetElem]) -> Option<CellElem> {
        if tets.len() != CELL_TETS {
            return None;
        }
        let mut v = Vec::with_capacity(CELL_VERTS);
        for t in tets {
            for &i in &t.v {
                if !v.contains(&i) {
                    v.push(i);
                }
            }
        }
        let v: [u32; CELL_VERTS] = v.try_into().ok()?;
        let local = |i: u32| v.iter().position(|&w| w == i).unwrap() as u8;
        let rest = CellRest {
            tets: std::array::from_fn(|e| tets[e].v.map(local)),
            // V_e det(B_e): V_e J_e = w_e det(Ds_e), prestrain included.
            weight: std::array::from_fn(|e| tets[e].rest.volume * tets[e].rest.b.determinant()),
            volume: tets.iter().map(|t| t.rest.volume).sum(),
            bulk: tets.iter().map(|t| t.lame.lambda * t.rest.volume).sum(),
            dilatation: Dilatation::of(tets[0].model),
        };
        Some(CellElem { v, rest })
    }

    /// The cells of a volume layer's tets, `cell_of[i]` naming tet i's cell (None: its own
    /// lambda term). A group of six over eight corners becomes a cell and its tets' lambda is
    /// zeroed; any other group keeps its tets' lambda terms.
    pub fn group(tets: &mut [TetElem], cell_of: &[Option<u32>]) -> Vec<CellElem> {
        let mut members = std::collections::BTreeMap::<u32, Vec<usize>>::new();
        for (i, c) in cell_of.iter().enumerate() {
            if let Some(c) = c {
                members.entry(*c).or_default().push(i);
            }
        }
        let mut cells = Vec::new();
        for group in members.values() {
            let elems: Vec<TetElem> = group.iter().map(|&i| tets[i]).collect();
            if let Some(c) = CellElem::from_tets(&elems) {
                cells.push(c);
                group.iter().for_each(|&i| tets[i].lame.lambda = 0.0);
            }
        }
        cells
    }
}

impl Element for CellElem {
    type Vertices = [u32; CELL_VERTS];
    type Local = Derivatives<{ 3 * CELL_VERTS }>;
    const PART: Part = Part::Volume;
    fn vertices(&self) -> [u32; CELL_VERTS] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        cell::energy(&self.rest, &gather(x, &self.v))
    }
    fn eval(&self, x: &[DVec3], filter: Filter) -> Self::Local {
        cell::eval(&self.rest, &gather(x, &self.v), filter)
    }
    fn unit_energy(&self, _length: f64) -> f64 {
        self.rest.bulk.abs()
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        CellElem { v: renumbered(self.v, to), ..*self }
    }
}
