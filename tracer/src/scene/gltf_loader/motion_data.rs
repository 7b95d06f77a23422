//! A scene's moving parts as two flat streams, one of integers and one of floats, for a scene
//! bundle's motion section (`tracer::bundle`, entries `motion.ints` and `motion.floats`): the
//! kept [`Motion`] and what posing it rewrites (the placed meshes and their instances). Reading
//! bounds every count by what the streams still hold (so a corrupt count allocates nothing
//! large) and every index by what it names, and refuses non-finite floats, so that a decoded
//! motion poses without a panic.
//!
//! The order, each list as its count (an integer) then its elements; floats in the float
//! stream at the same point of the walk, matrices as 16 column-major floats:
//! ```text
//! nodes      per node: parent (u32::MAX: a root), has a matrix (0/1)
//!            | floats: translation 3, rotation 4 (x y z w), scale 3, the matrix when it has one
//! channels   per channel: node, target (0 translation, 1 rotation, 2 scale, 3 weights),
//!            interpolation (0 STEP, 1 LINEAR, 2 CUBICSPLINE), components, keyframes K
//!            | floats: K times (non-decreasing), then K x (3 for CUBICSPLINE, else 1) x components values
//! rigid      per placement: instance, node | floats: its local matrix
//! deformed   per mesh: mesh, node, glTF mesh, has a skin (0/1)
//!            [skin: joint count J, J joint nodes | floats: J inverse bind matrices]
//!            rest weights W | floats: W weights
//!            primitives, per primitive: material, vertices V, triangles T, which of normals,
//!            uvs, uvs1, tangents, vertex skin it has (bits 0..4), morph targets M, per target
//!            which of positions, normals it has (bits 0..1); T x 3 vertex indices; V x 4 joints
//!            (with a vertex skin) | floats: V x 3 positions, V x 3 normals, V x 2 uvs, V x 2 uvs1,
//!            T x 12 tangents, V x 4 weights, per target V x 3 positions, V x 3 normals (each when
//!            present)
//! meshes     per mesh: triangles T, T materials | floats: T x 42 (positions 9, normals 9, uvs 6,
//!            uvs1 6, tangents 12)
//! instances  per instance: mesh | floats: its transform
//! ```

use super::animation::{Channel, Interpolation, Keyframes, RestTransform, Target};
use super::morph::MorphTarget;
use super::motion::{DeformedMesh, RigNode, RigidPlacement};
use super::nodes::{LocalPrimitive, VertexSkin};
use super::skin::SkinJoints;
use super::*;
use crate::scene::{Aabb, Instance, Mesh};

/// A moving scene's parts as streams (`None` for a scene without motion): the animation's name,
/// the integers, the floats.
pub fn motion_streams(scene: &Scene) -> Option<(String, Vec<u32>, Vec<f32>)> {
    let motion = scene.motion.as_ref()?;
    let mut w = Streams::default();
    motion.write(&mut w);
    w.count(scene.meshes.len());
    for mesh in &scene.meshes {
        w.count(mesh.triangles.len());
        for t in &mesh.triangles {
            w.ints.push(t.material);
            t.positions.iter().chain(&t.normals).for_each(|v| w.floats.extend(v.to_array()));
            t.uvs.iter().chain(&t.uvs1).for_each(|v| w.floats.extend(v.to_array()));
            t.tangents.iter().for_each(|v| w.floats.extend(v.to_array()));
        }
    }
    w.count(scene.instances.len());
    for i in &scene.instances {
        w.ints.push(i.mesh);
        w.matrix(&i.transform);
    }
    Some((motion.name().to_owned(), w.ints, w.floats))
}

/// The moving parts read back: a scene holding only its meshes, instances and motion, posed as
/// the streams were written (its static triangles, materials and the rest travel in the
/// bundle's packed scene). An error names what is wrong.
pub fn moving_from_streams(name: &str, ints: &[u32], floats: &[f32]) -> Result<Scene, String> {
    if let Some(at) = floats.iter().position(|f| !f.is_finite()) {
        return Err(format!("float {at} ({}) is not finite", floats[at]));
    }
    let mut r = Read { ints, floats, i: 0, f: 0 };
    let mut motion = Motion::read(&mut r, name.to_owned())?;
    let mut meshes = Vec::new();
    for _ in 0..r.count(1, 0)? {
        let count = r.count(1, 42)?;
        let mut triangles = Vec::with_capacity(count);
        for _ in 0..count {
            let material = r.int()?;
            let v = r.floats(42)?;
            let v3 = |k: usize| Vec3::from_slice(&v[k..]);
            let v2 = |k: usize| Vec2::from_slice(&v[k..]);
            triangles.push(Triangle {
                positions: [v3(0), v3(3), v3(6)],
                normals: [v3(9), v3(12), v3(15)],
                uvs: [v2(18), v2(20), v2(22)],
                uvs1: [v2(24), v2(26), v2(28)],
                tangents: [30, 34, 38].map(|k| Vec4::from_slice(&v[k..])),
                material,
            });
        }
        meshes.push(Mesh { triangles });
    }
    let mut instances = Vec::new();
    for i in 0..r.count(1, 16)? {
        let mesh = r.index(meshes.len(), "an instance's mesh")? as u32;
        let transform = r.matrix()?;
        let instance = Instance { mesh, transform };
        if !instance.has_valid_transform() {
            return Err(format!("instance {i}: its transform is not affine or not invertible"));
        }
        instances.push(instance);
    }
    if r.i != ints.len() || r.f != floats.len() {
        return Err(format!(
            "{} integers and {} floats follow the last instance",
            ints.len() - r.i,
            floats.len() - r.f
        ));
    }
    motion.attach(&meshes, &instances)?;
    Ok(Scene { meshes, instances, motion: Some(motion), ..Scene::default() })
}

#[derive(Default)]
struct Streams {
    ints: Vec<u32>,
    floats: Vec<f32>,
}

impl Streams {
    fn count(&mut self, n: usize) {
        self.ints.push(n as u32);
    }
    fn matrix(&mut self, m: &Mat4) {
        self.floats.extend(m.to_cols_array());
    }
    fn vecs<const N: usize>(&mut self, v: impl IntoIterator<Item = [f32; N]>) {
        v.into_iter().for_each(|a| self.floats.extend(a));
    }
}

/// A bounded cursor over both streams.
struct Read<'a> {
    ints: &'a [u32],
    floats: &'a [f32],
    i: usize,
    f: usize,
}

impl<'a> Read<'a> {
    fn int(&mut self) -> Result<u32, String> {
        let v = *self.ints.get(self.i).ok_or("the integers end early")?;
        self.i += 1;
        Ok(v)
    }

    fn floats(&mut self, n: usize) -> Result<&'a [f32], String> {
        let end = self.f.checked_add(n).filter(|&e| e <= self.floats.len()).ok_or("the floats end early")?;
        let out = &self.floats[self.f..end];
        self.f = end;
        Ok(out)
    }

    /// A count of elements that each take at least `ints` integers and `floats` floats: more
    /// than the streams still hold is an error (before anything is allocated for them).
    fn count(&mut self, ints: u64, floats: u64) -> Result<usize, String> {
        let n = self.int()? as u64;
        let (left_i, left_f) = ((self.ints.len() - self.i) as u64, (self.floats.len() - self.f) as u64);
        if n * ints > left_i || n * floats > left_f || (ints == 0 && floats == 0 && n > left_i + left_f) {
            return Err(format!("a count of {n} is more than the streams hold"));
        }
        Ok(n as usize)
    }

    fn index(&mut self, bound: usize, what: &str) -> Result<usize, String> {
        let v = self.int()? as usize;
        if v >= bound {
            return Err(format!("{what} is {v}, of {bound}"));
        }
        Ok(v)
    }

    fn flag(&mut self, bits: u32, what: &str) -> Result<u32, String> {
        let v = self.int()?;
        if v >> bits != 0 {
            return Err(format!("{what} has unknown bits ({v:#x})"));
        }
        Ok(v)
    }

    fn matrix(&mut self) -> Result<Mat4, String> {
        Ok(Mat4::from_cols_slice(self.floats(16)?))
    }

    fn vecs<T>(&mut self, count: usize, n: usize, make: impl Fn(&[f32]) -> T) -> Result<Vec<T>, String> {
        Ok(self.floats(count * n)?.chunks_exact(n).map(make).collect())
    }
}

const TARGETS: [Target; 4] = [Target::Translation, Target::Rotation, Target::Scale, Target::Weights];
const INTERPOLATIONS: [Interpolation; 3] = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline];

impl Motion {
    fn write(&self, w: &mut Streams) {
        let (nodes, channels, rigid, deformed) = self.parts();
        w.count(nodes.len());
        for node in nodes {
            w.ints.extend([node.parent.map_or(u32::MAX, |p| p as u32), node.matrix.is_some() as u32]);
            let r = &node.rest;
            w.floats
                .extend(r.translation.to_array().into_iter().chain(r.rotation.to_array()).chain(r.scale.to_array()));
            if let Some(m) = &node.matrix {
                w.matrix(m);
            }
        }
        w.count(channels.len());
        for c in channels {
            let k = &c.keys;
            let target = TARGETS.iter().position(|t| *t == c.target).expect("a known target");
            let interpolation = INTERPOLATIONS.iter().position(|i| *i == k.interpolation).expect("known");
            w.ints.extend([c.node as u32, target as u32, interpolation as u32, k.n as u32, k.times.len() as u32]);
            w.floats.extend(&k.times);
            w.floats.extend(&k.values);
        }
        w.count(rigid.len());
        for p in rigid {
            w.ints.extend([p.instance as u32, p.node as u32]);
            w.matrix(&p.local);
        }
        w.count(deformed.len());
        for d in deformed {
            w.ints.extend([d.mesh as u32, d.node as u32, d.gltf_mesh as u32, d.skin.is_some() as u32]);
            if let Some(skin) = &d.skin {
                w.count(skin.joints.len());
                w.ints.extend(skin.joints.iter().map(|&j| j as u32));
                skin.inverse_bind.iter().for_each(|m| w.matrix(m));
            }
            w.count(d.rest_weights.len());
            w.floats.extend(&d.rest_weights);
            w.count(d.prims.len());
            for p in &d.prims {
                write_primitive(p, w);
            }
        }
    }

    fn read(r: &mut Read, name: String) -> Result<Motion, String> {
        let count = r.count(2, 10)?;
        let mut nodes = Vec::with_capacity(count);
        for n in 0..count {
            let parent = match r.int()? {
                u32::MAX => None,
                p if (p as usize) < count && p as usize != n => Some(p as usize),
                p => return Err(format!("node {n}'s parent is {p}, of {count} nodes")),
            };
            let has_matrix = r.flag(1, "a node's matrix flag")? == 1;
            let f = r.floats(10)?;
            let rest = RestTransform {
                translation: Vec3::from_slice(&f[0..3]),
                rotation: Quat::from_slice(&f[3..7]),
                scale: Vec3::from_slice(&f[7..10]),
            };
            let matrix = if has_matrix { Some(r.matrix()?) } else { None };
            nodes.push(RigNode { parent, rest, matrix, moved: false, morphed: false });
        }
        let mut channels = Vec::new();
        for c in 0..r.count(5, 1)? {
            let node = r.index(nodes.len(), "a channel's node")?;
            let target = TARGETS[r.index(TARGETS.len(), "a channel's target")?];
            let interpolation = INTERPOLATIONS[r.index(INTERPOLATIONS.len(), "a channel's interpolation")?];
            let n = r.int()? as usize;
            let expected = match target {
                Target::Translation | Target::Scale => n == 3,
                Target::Rotation => n == 4,
                Target::Weights => n >= 1,
            };
            if !expected {
                return Err(format!("channel {c} animates {target:?} with {n} components"));
            }
            let keys = r.count(0, 1)?;
            if keys == 0 {
                return Err(format!("channel {c} has no keyframes"));
            }
            let times = r.floats(keys)?.to_vec();
            if times.windows(2).any(|w| w[1] < w[0]) {
                return Err(format!("channel {c}: keyframe times decrease"));
            }
            let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
            let len = (keys as u64) * per_key * n as u64;
            if len > (r.floats.len() - r.f) as u64 {
                return Err(format!("channel {c}: {keys} keyframes of {n} components are more than the floats hold"));
            }
            let values = r.floats(len as usize)?.to_vec();
            channels.push(Channel { node, target, keys: Keyframes { times, values, n, interpolation } });
        }
        let mut rigid = Vec::new();
        for _ in 0..r.count(2, 16)? {
            let instance = r.int()? as usize; // checked against the instances once they are read
            let node = r.index(nodes.len(), "a placement's node")?;
            // Its bounds come with the meshes (`Motion::attach`).
            rigid.push(RigidPlacement { instance, node, local: r.matrix()?, bounds: Aabb::EMPTY });
        }
        let mut deformed = Vec::new();
        for _ in 0..r.count(6, 0)? {
            let mesh = r.int()? as usize; // checked against the meshes once they are read
            let node = r.index(nodes.len(), "a deformed mesh's node")?;
            let gltf_mesh = r.int()? as usize;
            let skin = match r.flag(1, "a deformed mesh's skin flag")? {
                1 => {
                    let count = r.count(1, 16)?;
                    let joints = (0..count).map(|_| r.index(nodes.len(), "a joint")).collect::<Result<_, _>>()?;
                    let inverse_bind = (0..count).map(|_| r.matrix()).collect::<Result<_, _>>()?;
                    Some(SkinJoints { joints, inverse_bind })
                }
                _ => None,
            };
            let weights = r.count(0, 1)?;
            let rest_weights = r.floats(weights)?.to_vec();
            let mut prims = Vec::new();
            for _ in 0..r.count(5, 0)? {
                let joints = skin.as_ref().map_or(0, |s| s.joints.len());
                prims.push(read_primitive(r, joints)?);
            }
            let what = format!("node {node} mesh {gltf_mesh}");
            deformed.push(DeformedMesh { mesh, node, gltf_mesh, prims, skin, rest_weights, what });
        }
        let mut motion = Motion::of_nodes(nodes, channels, name);
        motion.set_parts(rigid, deformed);
        Ok(motion)
    }
}

fn write_primitive(p: &LocalPrimitive, w: &mut Streams) {
    let flags = [p.normals.is_some(), p.uvs.is_some(), p.uvs1.is_some(), p.tangents.is_some(), p.skin.is_some()];
    let flags = flags.iter().enumerate().fold(0, |acc, (bit, &on)| acc | (on as u32) << bit);
    w.ints.extend([p.material, p.positions.len() as u32, p.triangles.len() as u32, flags, p.morph.len() as u32]);
    for t in &p.morph {
        w.ints.push(t.positions.is_some() as u32 | (t.normals.is_some() as u32) << 1);
    }
    w.ints.extend(p.triangles.iter().flatten());
    if let Some(skin) = &p.skin {
        w.ints.extend(skin.joints.iter().flatten());
    }
    w.vecs(p.positions.iter().map(|v| v.to_array()));
    w.vecs(p.normals.iter().flatten().map(|v| v.to_array()));
    w.vecs(p.uvs.iter().flatten().map(|v| v.to_array()));
    w.vecs(p.uvs1.iter().flatten().map(|v| v.to_array()));
    w.vecs(p.tangents.iter().flatten().flatten().map(|v| v.to_array()));
    if let Some(skin) = &p.skin {
        w.vecs(skin.weights.iter().map(|v| v.to_array()));
    }
    for t in &p.morph {
        w.vecs(t.positions.iter().flatten().map(|v| v.to_array()));
        w.vecs(t.normals.iter().flatten().map(|v| v.to_array()));
    }
}

/// A primitive of a deformed mesh whose skin has `joints` joints (0 without a skin).
fn read_primitive(r: &mut Read, joints: usize) -> Result<LocalPrimitive, String> {
    let material = r.int()?;
    let vertices = r.count(0, 3)?;
    let triangles = r.count(3, 0)?;
    let flags = r.flag(5, "a primitive's flags")?;
    let has = |bit: u32| flags & 1 << bit != 0;
    let morph_count = r.count(1, 0)?;
    let morph_flags = (0..morph_count).map(|_| r.flag(2, "a morph target's flags")).collect::<Result<Vec<_>, _>>()?;
    let mut tris = Vec::with_capacity(triangles);
    for _ in 0..triangles {
        let mut corners = [0; 3];
        for c in &mut corners {
            *c = r.index(vertices, "a triangle's vertex")? as u32;
        }
        tris.push(corners);
    }
    let skin_joints = match has(4) {
        true if joints == 0 => return Err("a primitive has a vertex skin but its mesh no skin".into()),
        true => {
            if vertices as u64 * 4 > (r.ints.len() - r.i) as u64 {
                return Err(format!("{vertices} vertices' joints are more than the integers hold"));
            }
            let mut all = Vec::with_capacity(vertices);
            for _ in 0..vertices {
                let mut four = [0; 4];
                for j in &mut four {
                    *j = r.index(joints, "a vertex's joint")? as u32;
                }
                all.push(four);
            }
            Some(all)
        }
        false => None,
    };
    let v3 = |s: &[f32]| Vec3::from_slice(s);
    let v2 = |s: &[f32]| Vec2::from_slice(s);
    let positions = r.vecs(vertices, 3, v3)?;
    let normals = if has(0) { Some(r.vecs(vertices, 3, v3)?) } else { None };
    let uvs = if has(1) { Some(r.vecs(vertices, 2, v2)?) } else { None };
    let uvs1 = if has(2) { Some(r.vecs(vertices, 2, v2)?) } else { None };
    let tangents = match has(3) {
        true => Some(r.vecs(triangles, 12, |s| [0, 4, 8].map(|k| Vec4::from_slice(&s[k..])))?),
        false => None,
    };
    let skin = match skin_joints {
        Some(joints) => Some(VertexSkin { joints, weights: r.vecs(vertices, 4, Vec4::from_slice)? }),
        None => None,
    };
    let mut morph = Vec::with_capacity(morph_count);
    for f in morph_flags {
        let positions = if f & 1 != 0 { Some(r.vecs(vertices, 3, v3)?) } else { None };
        let normals = if f & 2 != 0 { Some(r.vecs(vertices, 3, v3)?) } else { None };
        morph.push(MorphTarget { positions, normals });
    }
    Ok(LocalPrimitive { positions, normals, uvs, uvs1, triangles: tris, tangents, material, skin, morph })
}
