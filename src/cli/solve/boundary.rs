//! The node lists of `fissure solve`: `--fixed FIXED.json` and `--enforced ENF.json`.
//!
//! In: the two JSON files' text, how nodes are numbered ([`NodeNumbering`]),
//! and the mesh (positions in m). Out: [`Prescription`], one value per
//! prescribed DOF (`3 * node + component`, m) with where it came from, or an
//! error naming the file, the entry (`[4]`, 0-based) or the JSON line and
//! column, and the problem. Formats:
//!
//! - FIXED.json: a list whose entries are a node (`12`: all three components
//!   held at 0) or `{"node": 12, "components": "xz"}` (only those held: a roller).
//! - ENF.json: a list of `{"node": 12, "displacement_m": [0.001, null, 0.0]}`;
//!   `null` leaves that component free.
//!
//! Stays true: a DOF prescribed twice must agree (fixed and enforced to 0 is
//! fixed; fixed and enforced to 0.001 is an error); every enforced value is
//! finite and no larger than the mesh's bounding-box diagonal; every connected
//! component of the mesh is held against all six rigid motions
//! ([`check_rigid_motions`]), so the stiffness factored after this is not
//! singular.

use std::fmt;
use std::path::Path;

use anyhow::{Context as _, bail};
use fissure::fsio::{self, Cap};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::mesh::quality::{NO_COMPONENT, components};
use nalgebra::{Matrix6, SymmetricEigen, Vector6};
use serde::Deserialize;
use serde::de::{self, MapAccess, Visitor};

/// Component bits: x = 1, y = 2, z = 4 (as written in the output's masks).
pub const ALL_COMPONENTS: u8 = 0b111;

/// How the `node` numbers in the JSON files name mesh nodes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NodeNumbering {
    /// 0-based position in the mesh file's node list (ParaView's Point ID).
    Index { count: usize },
    /// Gmsh node tags of the `.msh` file: `sorted` (tag, index) pairs, and
    /// `tags[index]`.
    GmshTags { sorted: Vec<(i64, u32)>, tags: Vec<i64> },
}

impl NodeNumbering {
    /// Gmsh numbering from the tag of every node in file order.
    pub fn gmsh(tags: &[i64]) -> Self {
        let mut sorted: Vec<(i64, u32)> = tags.iter().enumerate().map(|(i, &t)| (t, i as u32)).collect();
        sorted.sort_unstable();
        NodeNumbering::GmshTags { sorted, tags: tags.to_vec() }
    }

    /// The node index of a number from a JSON file, or why there is none.
    fn resolve(&self, number: i64) -> Result<u32, String> {
        match self {
            NodeNumbering::Index { count } => {
                if number >= 0 && (number as u64) < *count as u64 {
                    Ok(number as u32)
                } else {
                    Err(format!(
                        "node {number} is out of range: the mesh has {count} nodes, numbered 0 to {} in file order \
                         (for Gmsh node tags, pass --node-numbering gmsh-tag)",
                        count.saturating_sub(1)
                    ))
                }
            }
            NodeNumbering::GmshTags { sorted, .. } => match sorted.binary_search_by_key(&number, |&(t, _)| t) {
                Ok(k) => Ok(sorted[k].1),
                Err(_) => Err(format!(
                    "node {number} is not a node tag of the mesh (its Gmsh tags run from {} to {}, {} nodes)",
                    sorted.first().map_or(0, |t| t.0),
                    sorted.last().map_or(0, |t| t.0),
                    sorted.len()
                )),
            },
        }
    }

    /// The number a user gave for node `index` (the inverse of `resolve`).
    pub fn number_of(&self, index: u32) -> i64 {
        match self {
            NodeNumbering::Index { .. } => index as i64,
            NodeNumbering::GmshTags { tags, .. } => tags.get(index as usize).copied().unwrap_or(-1),
        }
    }

    /// Column name of the node number in the CSV.
    pub fn column(&self) -> &'static str {
        match self {
            NodeNumbering::Index { .. } => "node_index",
            NodeNumbering::GmshTags { .. } => "gmsh_node_tag",
        }
    }
}

/// One FIXED.json entry: a node and the components held at 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FixedEntry {
    node: i64,
    components: u8,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FixedObject {
    node: i64,
    components: Components,
}

/// A non-empty set of `x`, `y`, `z`, each at most once ("xz").
struct Components(u8);

impl<'de> Deserialize<'de> for Components {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        parse_components(&text).map(Components).map_err(de::Error::custom)
    }
}

fn parse_components(text: &str) -> Result<u8, String> {
    let mut mask = 0u8;
    for ch in text.chars() {
        let bit = match ch.to_ascii_lowercase() {
            'x' => 1,
            'y' => 2,
            'z' => 4,
            _ => return Err(format!("components \"{text}\": expected letters x, y, z (e.g. \"xz\"), found {ch:?}")),
        };
        if mask & bit != 0 {
            return Err(format!("components \"{text}\": {ch} appears twice"));
        }
        mask |= bit;
    }
    if mask == 0 {
        return Err("components \"\": name at least one of x, y, z".into());
    }
    Ok(mask)
}

impl<'de> Deserialize<'de> for FixedEntry {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct EntryVisitor;
        impl<'de> Visitor<'de> for EntryVisitor {
            type Value = FixedEntry;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a node number, or {\"node\": N, \"components\": \"xz\"}")
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<FixedEntry, E> {
                Ok(FixedEntry { node: i64::try_from(v).unwrap_or(i64::MAX), components: ALL_COMPONENTS })
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<FixedEntry, E> {
                Ok(FixedEntry { node: v, components: ALL_COMPONENTS })
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<FixedEntry, A::Error> {
                let o = FixedObject::deserialize(de::value::MapAccessDeserializer::new(map))?;
                Ok(FixedEntry { node: o.node, components: o.components.0 })
            }
        }
        d.deserialize_any(EntryVisitor)
    }
}

/// One ENF.json entry; `null` components are free.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct EnforcedEntry {
    node: i64,
    displacement_m: [Option<f64>; 3],
}

/// Which file prescribed a DOF.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    Fixed,
    Enforced,
}

/// Every prescribed DOF with its value (m) and source, plus per-node masks.
#[derive(Debug, Clone, PartialEq)]
pub struct Prescription {
    /// `(3 * node + component, value in m)`, sorted by DOF, each DOF once.
    pub dofs: Vec<(usize, f64)>,
    /// Source of each entry of `dofs`.
    pub sources: Vec<Source>,
    /// Per node, the components FIXED.json holds (bits x = 1, y = 2, z = 4).
    pub fixed_mask: Vec<u8>,
    /// Per node, the components ENF.json prescribes (a component both files
    /// hold at 0 counts as fixed only).
    pub enforced_mask: Vec<u8>,
}

impl Prescription {
    /// Nodes with at least one component of `source`.
    pub fn node_count(&self, source: Source) -> usize {
        let mask = match source {
            Source::Fixed => &self.fixed_mask,
            Source::Enforced => &self.enforced_mask,
        };
        mask.iter().filter(|&&m| m != 0).count()
    }

    /// Prescribed components of `source`.
    pub fn dof_count(&self, source: Source) -> usize {
        self.sources.iter().filter(|&&s| s == source).count()
    }
}

fn read_json<T: de::DeserializeOwned>(path: &Path, what: &str) -> anyhow::Result<Vec<T>> {
    let text = fsio::read_regular_text(path, Cap::NODE_LIST).with_context(|| format!("cannot read the {what} list"))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a valid {what} list", path.display()))
}

/// Reads FIXED.json and ENF.json (either may be absent) into one prescription.
/// `positions` are in m.
pub fn load(
    fixed: Option<&Path>,
    enforced: Option<&Path>,
    numbering: &NodeNumbering,
    positions: &[Vec3],
) -> anyhow::Result<Prescription> {
    let fixed_entries: Vec<FixedEntry> = match fixed {
        Some(p) => read_json(p, "fixed-node")?,
        None => Vec::new(),
    };
    let enforced_entries: Vec<EnforcedEntry> = match enforced {
        Some(p) => read_json(p, "enforced-displacement")?,
        None => Vec::new(),
    };
    build(fixed, &fixed_entries, enforced, &enforced_entries, numbering, positions)
}

fn build(
    fixed_path: Option<&Path>,
    fixed: &[FixedEntry],
    enforced_path: Option<&Path>,
    enforced: &[EnforcedEntry],
    numbering: &NodeNumbering,
    positions: &[Vec3],
) -> anyhow::Result<Prescription> {
    let shown = |p: Option<&Path>| p.map_or_else(String::new, |p| p.display().to_string());
    let (fixed_name, enforced_name) = (shown(fixed_path), shown(enforced_path));
    let n = positions.len();
    let diagonal = bounding_diagonal(positions);
    let mut value: Vec<Option<(f64, Source, usize)>> = vec![None; 3 * n];
    let mut fixed_mask = vec![0u8; n];
    let mut enforced_mask = vec![0u8; n];
    for (k, e) in fixed.iter().enumerate() {
        let node = numbering.resolve(e.node).map_err(|why| anyhow::anyhow!("{fixed_name}: [{k}]: {why}"))? as usize;
        fixed_mask[node] |= e.components;
        for c in 0..3 {
            if e.components & (1 << c) != 0 {
                value[3 * node + c] = Some((0.0, Source::Fixed, k));
            }
        }
    }
    const AXES: [char; 3] = ['x', 'y', 'z'];
    for (k, e) in enforced.iter().enumerate() {
        let node = numbering.resolve(e.node).map_err(|why| anyhow::anyhow!("{enforced_name}: [{k}]: {why}"))? as usize;
        if e.displacement_m.iter().all(Option::is_none) {
            bail!("{enforced_name}: [{k}]: node {}: displacement_m is [null, null, null]; give at least one component", e.node);
        }
        for (c, v) in e.displacement_m.iter().enumerate() {
            let Some(v) = *v else { continue };
            if !v.is_finite() {
                bail!("{enforced_name}: [{k}]: node {}: displacement_m[{c}] = {v} is not a finite number", e.node);
            }
            if v.abs() > diagonal {
                bail!(
                    "{enforced_name}: [{k}]: node {}: displacement_m[{c}] = {v} m is larger than the whole mesh \
                     (bounding-box diagonal {diagonal:.4e} m); displacements are in metres whatever --units says",
                    e.node
                );
            }
            let dof = 3 * node + c;
            match value[dof] {
                Some((_, Source::Fixed, j)) if v != 0.0 => bail!(
                    "node {} component {} is fixed ({fixed_name}: [{j}]) and enforced to {v} m ({enforced_name}: [{k}]); \
                     remove one of them",
                    e.node,
                    AXES[c]
                ),
                Some((_, Source::Fixed, _)) => {}
                Some((w, Source::Enforced, j)) if w != v => bail!(
                    "{enforced_name}: node {} component {} is enforced twice with different values: {w} m ([{j}]) and {v} m ([{k}])",
                    e.node,
                    AXES[c]
                ),
                Some((_, Source::Enforced, _)) => {}
                None => {
                    value[dof] = Some((v, Source::Enforced, k));
                    enforced_mask[node] |= 1 << c;
                }
            }
        }
    }
    let mut dofs = Vec::new();
    let mut sources = Vec::new();
    for (d, v) in value.iter().enumerate() {
        if let Some((v, s, _)) = *v {
            dofs.push((d, v));
            sources.push(s);
        }
    }
    Ok(Prescription { dofs, sources, fixed_mask, enforced_mask })
}

/// Length of the bounding box's diagonal, m (0 for an empty list).
pub fn bounding_diagonal(positions: &[Vec3]) -> f64 {
    if positions.is_empty() {
        return 0.0;
    }
    let (lo, hi) = fissure::mesh::bounding_box(positions);
    (hi - lo).norm()
}

/// Errors unless every connected component of `mesh` (positions in m) is held
/// against every rigid motion `u(x) = a + w x (x - c)` by the prescribed DOFs:
/// the 6 x 6 matrix `sum over prescribed DOFs of g g^T`, `g = [e_c, (x - c) x e_c]`
/// (lengths scaled by the component's size), must have full rank. Without
/// this the stiffness is singular (or, with round-off, nearly so and the
/// answer garbage).
pub fn check_rigid_motions(mesh: &TetMesh, prescribed: &Prescription, numbering: &NodeNumbering) -> anyhow::Result<()> {
    if prescribed.dofs.is_empty() {
        bail!(
            "no fixed or enforced node: the mesh can move freely (rigid-body motion), so the static problem has no \
             unique solution; fix more nodes (--fixed) or enforce some (--enforced)"
        );
    }
    let comps = components(mesh);
    let count = comps.count;
    let mut centroid = vec![Vec3::zeros(); count];
    let mut nodes = vec![0usize; count];
    let mut lowest = vec![u32::MAX; count];
    for (v, &c) in comps.node_component.iter().enumerate() {
        if c == NO_COMPONENT {
            continue;
        }
        centroid[c as usize] += mesh.positions[v];
        nodes[c as usize] += 1;
        lowest[c as usize] = lowest[c as usize].min(v as u32);
    }
    for (c, n) in centroid.iter_mut().zip(&nodes) {
        *c /= (*n).max(1) as f64;
    }
    let mut radius2 = vec![0.0; count];
    for (v, &c) in comps.node_component.iter().enumerate() {
        if c != NO_COMPONENT {
            radius2[c as usize] += (mesh.positions[v] - centroid[c as usize]).norm_squared() / nodes[c as usize] as f64;
        }
    }
    let mut gram = vec![Matrix6::<f64>::zeros(); count];
    let mut held = vec![0usize; count];
    for &(dof, _) in &prescribed.dofs {
        let (v, axis) = (dof / 3, dof % 3);
        let c = comps.node_component[v];
        if c == NO_COMPONENT {
            continue;
        }
        let c = c as usize;
        let scale = radius2[c].sqrt().max(f64::MIN_POSITIVE);
        let r = (mesh.positions[v] - centroid[c]) / scale;
        let e = Vec3::ith(axis, 1.0);
        let w = r.cross(&e);
        let g = Vector6::new(e.x, e.y, e.z, w.x, w.y, w.z);
        gram[c] += g * g.transpose();
        held[c] += 1;
    }
    for c in 0..count {
        let eig = SymmetricEigen::new(gram[c]);
        let largest = eig.eigenvalues.max();
        let tolerance = 1e-9 * largest.max(1.0);
        let free: Vec<usize> = (0..6).filter(|&k| eig.eigenvalues[k] <= tolerance).collect();
        if free.is_empty() {
            continue;
        }
        let mode = eig.eigenvectors.column(free[0]);
        let (a, w) = (Vec3::new(mode[0], mode[1], mode[2]), Vec3::new(mode[3], mode[4], mode[5]));
        let example = if w.norm() < 1e-6 {
            format!("e.g. a translation along {}", direction(a))
        } else {
            format!("e.g. a rotation about an axis along {}", direction(w))
        };
        bail!(
            "the mesh can move freely: connected component {c} of {count} ({} nodes, lowest node {}) has {} prescribed \
             component{} and {} of its 6 rigid motions are not held ({example}); fix more nodes of it (at least three \
             nodes not on one line, or rollers that stop every translation and rotation)",
            nodes[c],
            numbering.number_of(lowest[c]),
            held[c],
            if held[c] == 1 { "" } else { "s" },
            free.len()
        );
    }
    Ok(())
}

/// A unit direction as text, its largest component positive, no `-0.000`.
fn direction(v: Vec3) -> String {
    let v = v.normalize();
    let v = if v[v.iamax()] < 0.0 { -v } else { v };
    let c = |x: f64| if x.abs() < 5e-4 { 0.0 } else { x };
    format!("({:.3}, {:.3}, {:.3})", c(v.x), c(v.y), c(v.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use fissure::mesh::fixtures::{box_mesh, linspace};

    fn fixed_of(json: &str) -> Result<Vec<FixedEntry>, serde_json::Error> {
        serde_json::from_str(json)
    }

    #[test]
    fn fixed_entries_are_nodes_or_rollers() {
        let e = fixed_of(r#"[3, {"node": 4, "components": "xz"}, {"node": 5, "components": "Y"}]"#).expect("valid");
        assert_eq!(e, vec![
            FixedEntry { node: 3, components: 0b111 },
            FixedEntry { node: 4, components: 0b101 },
            FixedEntry { node: 5, components: 0b010 },
        ]);
        for (bad, says) in [
            (r#"[1, {"node": 2, "components": "xw"}]"#, "expected letters x, y, z"),
            (r#"[1, {"node": 2, "components": "xx"}]"#, "appears twice"),
            (r#"[1, {"node": 2, "components": ""}]"#, "at least one"),
            (r#"[1, {"node": 2, "comp": "x"}]"#, "unknown field `comp`"),
            (r#"[1, 2.5]"#, "expected a node number"),
            ("[1,\n 2,,]", "line 2 column 4"),
        ] {
            let e = fixed_of(bad).expect_err(bad).to_string();
            assert!(e.contains(says), "{bad}: {e} should say {says}");
        }
        let e = fixed_of("[1,\n {\"node\": 2, \"components\": \"q\"}]").expect_err("q").to_string();
        assert!(e.contains("line 2"), "a bad component names its line: {e}");
    }

    fn cube() -> TetMesh {
        box_mesh(&linspace(0.0, 1.0, 3), &linspace(0.0, 1.0, 3), &linspace(0.0, 1.0, 3)).expect("box")
    }

    fn prescribe(mesh: &TetMesh, fixed: &[FixedEntry], enforced: &[EnforcedEntry]) -> anyhow::Result<Prescription> {
        let numbering = NodeNumbering::Index { count: mesh.node_count() };
        build(Some(Path::new("F.json")), fixed, Some(Path::new("E.json")), enforced, &numbering, &mesh.positions)
    }

    #[test]
    fn conflicts_ranges_and_absurd_values_are_refused_naming_the_file() {
        let m = cube();
        let all = |node| FixedEntry { node, components: ALL_COMPONENTS };
        let enf = |node, d: [Option<f64>; 3]| EnforcedEntry { node, displacement_m: d };
        let ok = prescribe(&m, &[all(0), all(0)], &[enf(0, [Some(0.0), None, None]), enf(1, [Some(0.1), None, Some(0.0)])]).expect("agreeing");
        assert_eq!(ok.dofs, vec![(0, 0.0), (1, 0.0), (2, 0.0), (3, 0.1), (5, 0.0)]);
        assert_eq!(ok.sources, vec![Source::Fixed, Source::Fixed, Source::Fixed, Source::Enforced, Source::Enforced]);
        assert_eq!((ok.fixed_mask[0], ok.enforced_mask[0], ok.enforced_mask[1]), (0b111, 0, 0b101));
        for (fixed, enforced, says) in [
            (vec![all(64)], vec![], "F.json: [0]: node 64 is out of range: the mesh has 64 nodes, numbered 0 to 63"),
            (vec![all(-1)], vec![], "F.json: [0]: node -1 is out of range"),
            (vec![all(3)], vec![enf(3, [None, Some(1e-3), None])], "node 3 component y is fixed (F.json: [0]) and enforced to 0.001 m (E.json: [0])"),
            (vec![], vec![enf(2, [Some(1e-3), None, None]), enf(2, [Some(2e-3), None, None])], "enforced twice"),
            (vec![], vec![enf(2, [Some(f64::NAN), None, None])], "not a finite number"),
            (vec![], vec![enf(2, [Some(2.0), None, None])], "larger than the whole mesh (bounding-box diagonal 1.7321e0 m)"),
            (vec![], vec![enf(2, [None, None, None])], "at least one component"),
        ] {
            let e = format!("{:#}", prescribe(&m, &fixed, &enforced).expect_err(says));
            assert!(e.contains(says), "{e}\nshould say: {says}");
        }
    }

    #[test]
    fn gmsh_tags_resolve_to_file_order() {
        let n = NodeNumbering::gmsh(&[10, 3, 7]);
        assert_eq!((n.resolve(10), n.resolve(3), n.resolve(7)), (Ok(0), Ok(1), Ok(2)));
        assert!(n.resolve(0).expect_err("no tag 0").contains("tags run from 3 to 10"));
        assert_eq!(n.number_of(2), 7);
    }

    #[test]
    fn rigid_motions_must_all_be_held_in_every_component() {
        let m = cube();
        let numbering = NodeNumbering::Index { count: m.node_count() };
        let held = |fixed: &[FixedEntry]| {
            let p = prescribe(&m, fixed, &[]).expect("valid");
            check_rigid_motions(&m, &p, &numbering).map_err(|e| e.to_string())
        };
        let all = |node| FixedEntry { node, components: ALL_COMPONENTS };
        let nodes_at = |pred: &dyn Fn(&Vec3) -> bool| -> Vec<i64> {
            m.positions.iter().enumerate().filter(|(_, p)| pred(p)).map(|(i, _)| i as i64).collect()
        };
        // one node, and a line of nodes: a rotation stays free
        let e = held(&[all(0)]).expect_err("one node");
        assert!(e.contains("3 of its 6 rigid motions") && e.contains("fix more nodes"), "{e}");
        let line: Vec<FixedEntry> = nodes_at(&|p| p.y == 0.0 && p.z == 0.0).into_iter().map(all).collect();
        let e = held(&line).expect_err("collinear");
        assert!(e.contains("1 of its 6") && e.contains("rotation about an axis along (1.000, 0.000, 0.000)"), "{e}");
        // rollers (x) on the face x = 0 only: y, z translations and the x rotation free
        let rollers: Vec<FixedEntry> = nodes_at(&|p| p.x == 0.0).into_iter().map(|node| FixedEntry { node, components: 1 }).collect();
        assert!(held(&rollers).expect_err("rollers alone").contains("3 of its 6"));
        // the patch-test rollers: x on x = 0, y on y = 0, z on z = 0: held
        let mut sym = rollers.clone();
        sym.extend(nodes_at(&|p| p.y == 0.0).into_iter().map(|node| FixedEntry { node, components: 2 }));
        sym.extend(nodes_at(&|p| p.z == 0.0).into_iter().map(|node| FixedEntry { node, components: 4 }));
        held(&sym).expect("symmetry rollers hold every rigid motion");
        // two disjoint cubes (as the two hemispheres): holding the first leaves the second free
        let mut two = cube();
        let offset = two.node_count() as u32;
        let mut positions = two.positions.clone();
        positions.extend(two.positions.iter().map(|p| p + Vec3::new(3.0, 0.0, 0.0)));
        let mut tets = two.tets.clone();
        tets.extend(two.tets.iter().map(|t| t.map(|v| v + offset)));
        two = TetMesh::new(positions, tets, vec![]).expect("two cubes");
        let numbering2 = NodeNumbering::Index { count: two.node_count() };
        let p = build(None, &sym, None, &[], &numbering2, &two.positions).expect("valid");
        let e = check_rigid_motions(&two, &p, &numbering2).expect_err("second cube free").to_string();
        assert!(e.contains("component 1 of 2 (64 nodes, lowest node 64) has 0 prescribed components and 6 of its 6"), "{e}");
        let e = check_rigid_motions(&m, &prescribe(&m, &[], &[]).expect("empty"), &numbering).expect_err("nothing");
        assert!(e.to_string().contains("no fixed or enforced node: the mesh can move freely"), "{e}");
    }
}
