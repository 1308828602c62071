//! Raw tetrahedra as a file states them, turned into a validated [`TetMesh`].
//!
//! In: node tags (arbitrary integers, in file order) with positions, and tets
//! as tag quadruples with their region and the file line they came from. Out: a
//! [`TetMesh`] with nodes in file order, or an error naming the line of the
//! element or node at fault. Stays true: tags map to indices without iterating a
//! hash map (a dense table, a constant offset, or a sorted list), so the result
//! does not depend on anything but the file.

use std::path::Path;

use super::error::{MeshFileError, MeshFileErrorKind as K};
use crate::math::Vec3;
use crate::mesh::{MeshError, TetMesh};

/// Where something is in a file: a 1-based line (text) or a byte offset (binary).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Place {
    Line(u32),
    Byte(u64),
    Nowhere,
}

impl Place {
    pub fn line(line: usize) -> Self {
        Place::Line(line.min(u32::MAX as usize) as u32)
    }
    pub fn error(self, path: &Path, kind: K) -> MeshFileError {
        match self {
            Place::Line(l) => MeshFileError::at_line(path, l as usize, kind),
            Place::Byte(b) => MeshFileError::at_offset(path, b as usize, kind),
            Place::Nowhere => MeshFileError::new(path, kind),
        }
    }
}

/// Nodes and tets as read, before tags are resolved and the mesh validated.
#[derive(Debug, Default)]
pub(crate) struct RawTets {
    pub node_tags: Vec<i64>,
    pub node_places: Vec<Place>,
    pub positions: Vec<Vec3>,
    pub tet_nodes: Vec<[i64; 4]>,
    pub tet_tags: Vec<i64>,
    pub tet_places: Vec<Place>,
    pub regions: Vec<u32>,
}

/// Tag -> node index.
enum NodeMap {
    /// tag = first + index.
    Offset { first: i64, count: usize },
    /// table[tag - min] = index or u32::MAX.
    Dense { min: i64, table: Vec<u32> },
    /// Sorted (tag, index).
    Sorted(Vec<(i64, u32)>),
}

impl NodeMap {
    fn get(&self, tag: i64) -> Option<u32> {
        match self {
            NodeMap::Offset { first, count } => {
                let k = tag.checked_sub(*first)?;
                (k >= 0 && (k as u64) < *count as u64).then_some(k as u32)
            }
            NodeMap::Dense { min, table } => {
                let k = tag.checked_sub(*min)?;
                let v = *table.get(usize::try_from(k).ok()?)?;
                (v != u32::MAX).then_some(v)
            }
            NodeMap::Sorted(v) => v.binary_search_by_key(&tag, |&(t, _)| t).ok().map(|i| v[i].1),
        }
    }
}

impl RawTets {
    pub fn push_node(&mut self, tag: i64, position: Vec3, place: Place) {
        self.node_tags.push(tag);
        self.positions.push(position);
        self.node_places.push(place);
    }

    pub fn push_tet(&mut self, tag: i64, nodes: [i64; 4], region: u32, place: Place) {
        self.tet_tags.push(tag);
        self.tet_nodes.push(nodes);
        self.regions.push(region);
        self.tet_places.push(place);
    }

    fn node_map(&self, path: &Path) -> Result<NodeMap, MeshFileError> {
        let tags = &self.node_tags;
        let n = tags.len();
        if n > u32::MAX as usize - 1 {
            return Err(MeshFileError::new(path, K::Unsupported(format!("{n} nodes (at most 2^32 - 2)"))));
        }
        let Some(&first) = tags.first() else {
            return Ok(NodeMap::Offset { first: 0, count: 0 });
        };
        if tags.iter().enumerate().all(|(i, &t)| first.checked_add(i as i64) == Some(t)) {
            return Ok(NodeMap::Offset { first, count: n });
        }
        let min = *tags.iter().min().unwrap_or(&0);
        let max = *tags.iter().max().unwrap_or(&0);
        let duplicate = |index: usize| self.node_places[index].error(path, K::DuplicateNode { node: tags[index] });
        let span = (max as i128 - min as i128) as u128;
        if span < 4 * n as u128 + 1024 {
            let mut table = vec![u32::MAX; span as usize + 1];
            for (i, &t) in tags.iter().enumerate() {
                let slot = &mut table[(t as i128 - min as i128) as usize];
                if *slot != u32::MAX {
                    return Err(duplicate(i));
                }
                *slot = i as u32;
            }
            return Ok(NodeMap::Dense { min, table });
        }
        let mut sorted: Vec<(i64, u32)> = tags.iter().enumerate().map(|(i, &t)| (t, i as u32)).collect();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(duplicate(w[1].1 as usize));
        }
        Ok(NodeMap::Sorted(sorted))
    }

    /// Resolves tags and validates into a [`TetMesh`].
    pub fn finish(self, path: &Path) -> Result<TetMesh, MeshFileError> {
        if self.positions.is_empty() {
            return Err(MeshFileError::new(path, K::Empty("nodes")));
        }
        if self.tet_nodes.is_empty() {
            return Err(MeshFileError::new(path, K::Empty("tetrahedra")));
        }
        for (i, p) in self.positions.iter().enumerate() {
            if !crate::math::is_finite3(p) {
                return Err(self.node_places[i].error(path, K::NonFiniteCoordinate { node: self.node_tags[i] }));
            }
        }
        let map = self.node_map(path)?;
        let mut tets = Vec::with_capacity(self.tet_nodes.len());
        for (t, nodes) in self.tet_nodes.iter().enumerate() {
            let mut tet = [0u32; 4];
            for (k, &tag) in nodes.iter().enumerate() {
                tet[k] = map.get(tag).ok_or_else(|| {
                    self.tet_places[t].error(path, K::UnknownNode { element: self.tet_tags[t], node: tag })
                })?;
            }
            tets.push(tet);
        }
        let RawTets { positions, regions, tet_places, node_places, .. } = self;
        TetMesh::new(positions, tets, regions).map_err(|e| {
            let place = match &e {
                MeshError::NonFiniteNode { node, .. } => node_places.get(*node).copied(),
                MeshError::IndexOutOfRange { tet, .. }
                | MeshError::RepeatedNode { tet, .. }
                | MeshError::ZeroVolume { tet, .. } => tet_places.get(*tet).copied(),
                MeshError::Empty | MeshError::RegionCount { .. } => None,
            };
            place.unwrap_or(Place::Nowhere).error(path, K::Mesh(e))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(raw: &mut RawTets, tags: [i64; 4]) {
        let p = [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        for (k, &t) in tags.iter().enumerate() {
            raw.push_node(t, p[k], Place::line(k + 1));
        }
        raw.push_tet(1, tags, 7, Place::line(9));
    }

    #[test]
    fn sparse_and_offset_tags_resolve_to_file_order() {
        for tags in [[1, 2, 3, 4], [0, 1, 2, 3], [10, 3, 7, 5], [1, 1_000_000_000, 5, 9]] {
            let mut raw = RawTets::default();
            unit(&mut raw, tags);
            let m = raw.finish(Path::new("t")).expect("valid tet");
            assert_eq!(m.regions, vec![7]);
            let mut sorted = m.tets[0];
            sorted.sort_unstable();
            assert_eq!(sorted, [0, 1, 2, 3], "tags {tags:?} must map to indices 0..4 in file order");
        }
    }

    #[test]
    fn duplicate_and_unknown_tags_are_errors_with_lines() {
        let mut raw = RawTets::default();
        unit(&mut raw, [1, 2, 3, 5]);
        raw.node_tags[3] = 2;
        let e = raw.finish(Path::new("t")).expect_err("node 2 twice");
        assert!(matches!(e.kind, K::DuplicateNode { node: 2 }), "{e}");
        assert_eq!(e.line, Some(4));
        let mut raw = RawTets::default();
        unit(&mut raw, [1, 2, 3, 4]);
        raw.tet_nodes[0][2] = 99;
        let e = raw.finish(Path::new("t")).expect_err("node 99 undefined");
        assert_eq!(e.to_string(), "t:9: element 1 refers to node 99, which the file does not define");
    }
}
