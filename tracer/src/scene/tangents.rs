//! Tangents for normal mapping: generated with MikkTSpace (the `bevy_mikktspace` crate, a port
//! of the reference implementation that Blender, the glTF sample viewer and most bakers use, so
//! that normal maps baked against it shade as their authors saw them) when a file has none.

use glam::{Vec2, Vec3, Vec4};

/// An indexed triangle mesh in one space, read by MikkTSpace, which writes per-corner tangents.
struct Mesh<'a> {
    positions: &'a [Vec3],
    normals: Option<&'a [Vec3]>,
    uvs: &'a [Vec2],
    triangles: &'a [[u32; 3]],
    tangents: Vec<[Vec4; 3]>,
}

impl Mesh<'_> {
    fn corner(&self, face: usize, vert: usize) -> usize {
        self.triangles.get(face).map_or(0, |t| t[vert.min(2)] as usize)
    }

    fn face_normal(&self, face: usize) -> Vec3 {
        let p = |v| self.positions.get(self.corner(face, v)).copied().unwrap_or(Vec3::ZERO);
        (p(1) - p(0)).cross(p(2) - p(0)).normalize_or(Vec3::Z)
    }
}

impl bevy_mikktspace::Geometry for Mesh<'_> {
    fn num_faces(&self) -> usize {
        self.triangles.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions.get(self.corner(face, vert)).copied().unwrap_or(Vec3::ZERO).to_array()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let n = self.normals.and_then(|n| n.get(self.corner(face, vert)).copied()).unwrap_or(Vec3::ZERO);
        // Zero or non-unit file normals would make MikkTSpace's projections degenerate.
        n.try_normalize().unwrap_or_else(|| self.face_normal(face)).to_array()
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.uvs.get(self.corner(face, vert)).copied().unwrap_or(Vec2::ZERO).to_array()
    }

    fn set_tangent(&mut self, space: Option<bevy_mikktspace::TangentSpace>, face: usize, vert: usize) {
        let Some(tangent) = space.map(|s| s.tangent_encoded()) else {
            return; // no tangent for this corner: it stays zero
        };
        if let Some(t) = self.tangents.get_mut(face).and_then(|t| t.get_mut(vert)) {
            // MikkTSpace's bitangent follows +v; glTF's v runs down the image while a normal
            // map's green (+Y) points up it, so the handedness is negated (as three.js does
            // for glTF: `computeMikkTSpaceTangents(..., negateSign = true)`).
            *t = Vec4::new(tangent[0], tangent[1], tangent[2], -tangent[3]);
        }
    }
}

/// [`mikktspace_tangents`] for triangles given by their corners (MikkTSpace welds shared
/// vertices itself).
pub(crate) fn corner_tangents(triangles: &[&super::Triangle]) -> Option<Vec<[Vec4; 3]>> {
    let positions: Vec<Vec3> = triangles.iter().flat_map(|t| t.positions).collect();
    let normals: Vec<Vec3> = triangles.iter().flat_map(|t| t.normals).collect();
    let uvs: Vec<Vec2> = triangles.iter().flat_map(|t| t.uvs).collect();
    let indices: Vec<[u32; 3]> = (0..triangles.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    mikktspace_tangents(&positions, Some(&normals), &uvs, &indices)
}

/// MikkTSpace tangents of each corner of `triangles` (indices into the vertex arrays; the
/// loaders have checked them), xyz unit and w = ±1. `None` when MikkTSpace gives up (a mesh
/// without any usable triangle); corners it cannot orient (zero UV area) get zero tangents,
/// which the kernel treats as "no normal map here".
pub(crate) fn mikktspace_tangents(
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
) -> Option<Vec<[Vec4; 3]>> {
    let mut mesh = Mesh { positions, normals, uvs, triangles, tangents: vec![[Vec4::ZERO; 3]; triangles.len()] };
    bevy_mikktspace::generate_tangents(&mut mesh).ok()?;
    for t in mesh.tangents.iter_mut().flatten() {
        *t = unit_tangent(*t);
    }
    Some(mesh.tangents)
}

/// A tangent as the kernel expects it: xyz unit (zero when degenerate or not finite), w ±1.
pub(crate) fn unit_tangent(t: Vec4) -> Vec4 {
    match t.truncate().try_normalize() {
        Some(xyz) => xyz.extend(if t.w < 0.0 { -1.0 } else { 1.0 }),
        None => Vec4::ZERO,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_tangents_become_zero_and_handedness_a_sign() {
        assert_eq!(unit_tangent(Vec4::new(0.0, 0.0, 0.0, 1.0)), Vec4::ZERO);
        assert_eq!(unit_tangent(Vec4::new(f32::NAN, 0.0, 0.0, 1.0)), Vec4::ZERO);
        assert_eq!(unit_tangent(Vec4::new(2.0, 0.0, 0.0, -0.3)), Vec4::new(1.0, 0.0, 0.0, -1.0));
    }
}
