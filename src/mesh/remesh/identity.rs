//! What survives a remesh, by identity (REMESH.md): a face is its vertex set, an edge its
//! endpoints and, for a hinge, its two opposite vertices (a flipped quad is a new edge). The
//! ECS keeps a survivor's entity, spawns the new ones and despawns the lost ones.

use std::collections::HashMap;
use std::hash::Hash;

/// `v` sorted: the identity of a face's or an edge's vertices, whatever their order.
pub fn sorted<T: Ord, const N: usize>(mut v: [T; N]) -> [T; N] {
    v.sort_unstable();
    v
}

/// Matches `new` keys against `old` ones (each old key at most once): for each new key whether
/// it is new, and the indices of the old keys no new one matched, increasing.
pub fn match_keys<K: Hash + Eq>(
    old: impl IntoIterator<Item = K>,
    new: impl IntoIterator<Item = K>,
) -> (Vec<bool>, Vec<usize>) {
    let mut left: HashMap<K, usize> = old.into_iter().enumerate().map(|(i, k)| (k, i)).collect();
    let fresh = new.into_iter().map(|k| left.remove(&k).is_none()).collect();
    let mut lost: Vec<usize> = left.into_values().collect();
    lost.sort_unstable();
    (fresh, lost)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faces_match_by_vertex_set_and_the_unmatched_are_listed_in_order() {
        let old = [[1, 2, 3], [3, 2, 4], [4, 5, 3]];
        let new = [[2, 3, 1], [3, 4, 6], [4, 3, 5]];
        let (fresh, lost) = match_keys(old.map(sorted), new.map(sorted));
        assert_eq!(fresh, [false, true, false]);
        assert_eq!(lost, [1]);
        // A changed quad: same endpoints, other opposite vertices, a new edge.
        let (fresh, lost) = match_keys([([1, 2], Some([3, 4]))], [([1, 2], Some([3, 5]))]);
        assert_eq!((fresh, lost), (vec![true], vec![0]));
    }
}
