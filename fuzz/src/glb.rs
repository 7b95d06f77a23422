//! The GLB container (glTF's binary form), split and built, for mutations that edit the JSON
//! chunk of a `.glb` and for targets that wrap bytes in a small scene.

/// The JSON chunk and the BIN chunk (if any) of a well-formed GLB; `None` for anything else.
pub fn split(bytes: &[u8]) -> Option<(&[u8], Option<&[u8]>)> {
    if !bytes.starts_with(b"glTF") {
        return None;
    }
    let u32_at = |at: usize| bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let mut pos = 12;
    let mut json = None;
    let mut bin = None;
    while pos + 8 <= bytes.len() {
        let len = u32_at(pos)?;
        let kind = bytes.get(pos + 4..pos + 8)?;
        let content = bytes.get(pos + 8..(pos + 8).checked_add(len)?)?;
        match kind {
            b"JSON" if json.is_none() => json = Some(content),
            b"BIN\0" if bin.is_none() => bin = Some(content),
            _ => {}
        }
        pos += 8 + len;
    }
    Some((json?, bin))
}

/// A GLB of `json` and `bin` (the chunks padded to 4 bytes as the format requires).
pub fn build(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |n: usize| n.div_ceil(4) * 4;
    let total = 12 + 8 + pad(json.len()) + bin.map_or(0, |b| 8 + pad(b.len()));
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(pad(json.len()) as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json);
    out.resize(out.len() + pad(json.len()) - json.len(), b' ');
    if let Some(bin) = bin {
        out.extend_from_slice(&(pad(bin.len()) as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
        out.resize(out.len() + pad(bin.len()) - bin.len(), 0);
    }
    out
}

/// A GLB with one textured quad whose material shows `image` twice: as the base colour texture
/// (repeat) and as the emissive texture through a clamping sampler, so the loader probes it,
/// decodes it once, copies it for the second wrap mode and computes its emitted power, as it
/// would for a real file. The image is stored in a buffer view, after the quad's geometry.
pub fn textured_quad(image: &[u8]) -> Vec<u8> {
    let mut bin = Vec::with_capacity(92 + image.len());
    for p in [[-1.0f32, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
        p.iter().for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
    }
    for uv in [[0.0f32, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]] {
        uv.iter().for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin.extend_from_slice(image);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}}}},"emissiveTexture":{{"index":1}},"emissiveFactor":[1,1,1]}}],
"textures":[{{"source":0}},{{"source":0,"sampler":0}}],"samplers":[{{"wrapS":33071,"wrapT":33648}}],
"images":[{{"bufferView":3,"mimeType":"image/png"}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},{{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},
{{"buffer":0,"byteOffset":80,"byteLength":12}},{{"buffer":0,"byteOffset":92,"byteLength":{}}}],
"buffers":[{{"byteLength":{}}}]}}"#,
        image.len(),
        bin.len()
    );
    build(json.as_bytes(), Some(&bin))
}

/// A GLB whose one primitive is a Draco stream (`KHR_draco_mesh_compression`, required): a
/// bumpy 6 x 6 grid with positions, normals and UVs, EdgeBreaker-coded with quantised
/// attributes, the accessors without buffer views. Mutations of its BIN chunk reach the Draco
/// decoder; of its JSON, the extension's attribute ids and the accessors' counts.
pub fn draco_grid() -> Vec<u8> {
    use draco_core::{
        DataType, DecoderBuffer, EncoderBuffer, EncoderOptions, FaceIndex, GeometryAttributeType, Mesh, MeshDecoder,
        MeshEncoder, PointAttribute,
    };
    const SIDE: usize = 6;
    let attribute = |kind, values: &[f32], components: u8| {
        let mut a = PointAttribute::new();
        a.init(kind, components, DataType::Float32, false, values.len() / components as usize);
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        a.buffer_mut().write(0, &bytes);
        a
    };
    let (mut positions, mut normals, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
    for y in 0..SIDE {
        for x in 0..SIDE {
            let (u, v) = (x as f32 / (SIDE - 1) as f32, y as f32 / (SIDE - 1) as f32);
            positions.extend_from_slice(&[2.0 * u - 1.0, 0.2 * (6.0 * u).sin(), 2.0 * v - 1.0]);
            let n = glam::Vec3::new(-1.2 * (6.0 * u).cos(), 1.0, 0.0).normalize();
            normals.extend_from_slice(&n.to_array());
            uvs.extend_from_slice(&[u, v]);
        }
    }
    let mut mesh = Mesh::new();
    let ids = [
        mesh.add_attribute(attribute(GeometryAttributeType::Position, &positions, 3)),
        mesh.add_attribute(attribute(GeometryAttributeType::Normal, &normals, 3)),
        mesh.add_attribute(attribute(GeometryAttributeType::TexCoord, &uvs, 2)),
    ];
    mesh.set_num_faces(2 * (SIDE - 1) * (SIDE - 1));
    let mut f = 0;
    for y in 0..SIDE - 1 {
        for x in 0..SIDE - 1 {
            let a = (y * SIDE + x) as u32;
            let (b, c, d) = (a + 1, a + SIDE as u32, a + SIDE as u32 + 1);
            mesh.set_face(FaceIndex(f), [a.into(), c.into(), b.into()]);
            mesh.set_face(FaceIndex(f + 1), [b.into(), c.into(), d.into()]);
            f += 2;
        }
    }
    let mut options = EncoderOptions::new();
    for (id, bits) in ids.iter().zip([12, 8, 10]) {
        options.set_attribute_int(*id, "quantization_bits", bits);
    }
    let mut encoder = MeshEncoder::new();
    encoder.set_mesh(mesh);
    let mut out = EncoderBuffer::new();
    encoder.encode(&options, &mut out).expect("encode the Draco seed");
    let stream = out.data().to_vec();
    // The counts the decoder produces (EdgeBreaker may reorder and split points).
    let mut decoded = Mesh::new();
    MeshDecoder::new().decode(&mut DecoderBuffer::new(&stream), &mut decoded).expect("decode the Draco seed");
    let (points, indices) = (decoded.num_points(), decoded.num_faces() * 3);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"],
"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":3,
"extensions":{{"KHR_draco_mesh_compression":{{"bufferView":0,"attributes":{{"POSITION":{},"NORMAL":{},"TEXCOORD_0":{}}}}}}}}}]}}],
"accessors":[{{"componentType":5126,"count":{points},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}},
{{"componentType":5126,"count":{points},"type":"VEC3"}},{{"componentType":5126,"count":{points},"type":"VEC2"}},
{{"componentType":5125,"count":{indices},"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{len}}}],"buffers":[{{"byteLength":{len}}}]}}"#,
        ids[0],
        ids[1],
        ids[2],
        len = stream.len()
    );
    build(json.as_bytes(), Some(&stream))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn build_and_split_round_trip() {
        let glb = build(b"{\"a\":1}", Some(&[1, 2, 3]));
        assert_eq!(glb.len() % 4, 0);
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let (json, bin) = split(&glb).unwrap();
        assert_eq!(json, b"{\"a\":1} ");
        assert_eq!(bin.unwrap(), [1, 2, 3, 0]);
        assert!(split(b"{}").is_none());
    }

    #[test]
    fn the_draco_seed_loads() {
        let scene = tracer::scene::load_gltf_slice(&draco_grid(), None, &Default::default()).expect("loads");
        assert_eq!(scene.triangles.len(), 50);
    }
}
