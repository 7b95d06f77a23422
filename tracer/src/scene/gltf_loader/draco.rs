//! `KHR_draco_mesh_compression`: a primitive whose geometry is a Draco stream (a buffer view)
//! instead of its accessors' data. The stream is decoded with `draco-core`, a pure-Rust decoder
//! that also builds for the page (wasm32). Each decoded attribute replaces the data of the
//! accessor the primitive names for that semantic (the accessor still gives its type, count and
//! normalization), and the stream's faces replace the indices. Attributes the extension does
//! not name, and morph targets (which the extension does not compress: their accessors follow
//! the decoded vertex order), are read from their accessors as usual.
//!
//! [`PrimitiveData`] with [`Loader::vertex_f32`] and [`Loader::primitive_indices`] is the one
//! place a primitive's vertex data and indices are read, so the rest of the loader does not care
//! whether they came from Draco.
//!
//! Bad streams are errors naming the mesh and primitive: what the decoder refuses (truncated or
//! corrupt data), attribute ids the stream does not have, component counts or element counts
//! that differ from the accessors', indices out of range. The decoder's ceilings are the
//! accessors' own counts, so a stream cannot decode more points or faces than the file declares
//! (and accessors are capped by the loader's limits before anything is decoded), and at most
//! [`MAX_UNBACKED_POINTS`] points unless the stream is long enough to stand for more.

use std::collections::HashMap;

use draco_core::{DataType, DecodeLimits, DecoderBuffer, Mesh, MeshDecoder};

use super::*;

/// The extension's name.
pub(super) const EXTENSION: &str = "KHR_draco_mesh_compression";

/// Most bytes of attribute values one stream may decode to (the decoder's own ceiling, which
/// also counts attributes the primitive does not use).
const MAX_DECODED_BYTES: u64 = 1 << 30;
/// Most points a stream may decode to whatever its length: constant attribute values
/// entropy-code to almost nothing, so a stream of a few bytes can declare millions of points.
/// The cap of an accessor without a buffer view (zeros), for the same reason.
const MAX_UNBACKED_POINTS: u64 = 1 << 22;
/// Points allowed per byte of the stream beyond [`MAX_UNBACKED_POINTS`] (real streams spend
/// bytes per point: LittlestTokyo's 4 MB hold about 0.03 points per byte).
const MAX_POINTS_PER_BYTE: u64 = 16;
/// Decoded bytes allowed per point: 64 four-byte components, far more than any glTF primitive's
/// attributes (position, normal, tangent, two UV sets, colour, joints, weights: 26).
const MAX_DECODED_BYTES_PER_POINT: u64 = 256;

/// Where a primitive's vertex attributes and indices come from: its accessors, or the decoded
/// Draco stream for the accessors the extension names.
#[derive(Default)]
pub(super) struct PrimitiveData {
    draco: Option<Decoded>,
}

/// A decoded Draco stream, as the primitive's accessors see it.
struct Decoded {
    /// glTF accessor -> (components per vertex, the values as f32, normalized as glTF says).
    attributes: HashMap<usize, (usize, Vec<f32>)>,
    /// The stream's faces, three indices each, all below the point count.
    indices: Vec<u32>,
}

impl PrimitiveData {
    /// Whether the primitive's geometry came from a Draco stream.
    pub(super) fn is_draco(&self) -> bool {
        self.draco.is_some()
    }
}

impl Loader<'_> {
    /// Decodes the primitive's Draco stream when it has `KHR_draco_mesh_compression`; else the
    /// primitive is read from its accessors. `what` names the primitive.
    pub(super) fn primitive_data(
        &mut self,
        prim: &gltf::json::mesh::Primitive,
        mode: Mode,
        what: &str,
    ) -> Result<PrimitiveData, SceneError> {
        let Some(ext) = prim.extensions.as_ref().and_then(|e| e.others.get(EXTENSION)) else {
            return Ok(PrimitiveData::default());
        };
        let what = format!("{what} {EXTENSION}");
        if mode != Mode::Triangles {
            return Err(malformed(format!(
                "{what}: the primitive's mode is {mode:?}, but Draco streams hold triangle lists (TRIANGLES)"
            )));
        }
        let view = ext
            .get("bufferView")
            .and_then(Value::as_u64)
            .and_then(|v| usize::try_from(v).ok())
            .ok_or_else(|| malformed(format!("{what}: no \"bufferView\" index")))?;
        let ids = ext
            .get("attributes")
            .and_then(Value::as_object)
            .ok_or_else(|| malformed(format!("{what}: no \"attributes\" object")))?;
        if ids.is_empty() {
            return Err(malformed(format!("{what}: \"attributes\" names no attribute")));
        }
        // Each named semantic: its Draco id, the primitive's accessor for it and that accessor's shape.
        let mut wanted = Vec::with_capacity(ids.len());
        for (semantic, id) in ids {
            let id = id
                .as_u64()
                .and_then(|i| u32::try_from(i).ok())
                .ok_or_else(|| malformed(format!("{what}: {semantic}'s Draco attribute id {id} is not an id")))?;
            let accessor = prim
                .attributes
                .iter()
                .find(|(s, _)| semantic_name(s) == *semantic)
                .map(|(_, a)| a.value())
                .ok_or_else(|| {
                    malformed(format!("{what}: names attribute {semantic}, which the primitive does not have"))
                })?;
            let shape = self.buffers.shape(accessor, &format!("{what} {semantic}"))?;
            wanted.push((semantic.as_str(), id, accessor, shape));
        }
        let index_shape = match prim.indices {
            Some(a) => Some(self.buffers.shape(a.value(), &format!("{what} indices"))?),
            None => None,
        };
        let (bytes, _) = self.buffers.view(view).map_err(|e| malformed(format!("{what}: {e}")))?;
        // The decoder may produce no more than the accessors declare (they must agree exactly,
        // checked below), nor more points than the stream's length can stand for; this bounds
        // what a corrupt or hostile header can make it allocate.
        let points = wanted
            .iter()
            .map(|w| w.3.count as u64)
            .max()
            .unwrap_or(0)
            .min(MAX_UNBACKED_POINTS.max(bytes.len() as u64 * MAX_POINTS_PER_BYTE));
        let faces = index_shape.map_or(MAX_TRIANGLES as u64, |s| s.count as u64 / 3);
        let limits = DecodeLimits::default()
            .with_max_points(points)
            .with_max_faces(faces)
            .with_max_decoded_bytes(points.saturating_mul(MAX_DECODED_BYTES_PER_POINT).min(MAX_DECODED_BYTES));
        let mut mesh = Mesh::new();
        MeshDecoder::new().decode(&mut DecoderBuffer::new(bytes).with_limits(limits), &mut mesh).map_err(|e| {
            malformed(format!(
                "{what}: the Draco stream (bufferView {view}, {} bytes) cannot be decoded: {e}",
                bytes.len()
            ))
        })?;

        let n = mesh.num_points();
        let mut attributes = HashMap::with_capacity(wanted.len());
        for (semantic, id, accessor, shape) in wanted {
            let attribute = mesh.attribute_by_unique_id(id).ok_or_else(|| {
                malformed(format!(
                    "{what}: {semantic} is Draco attribute {id}, which the stream does not have ({} attributes)",
                    mesh.num_attributes()
                ))
            })?;
            if shape.count != n {
                return Err(malformed(format!(
                    "{what}: {semantic}'s accessor {accessor} has {} elements, the Draco stream {n} points",
                    shape.count
                )));
            }
            let components = usize::from(attribute.num_components());
            if components != shape.dims {
                return Err(malformed(format!(
                    "{what}: {semantic} has {components} components in the Draco stream, {} in accessor {accessor}",
                    shape.dims
                )));
            }
            let mut values = attribute.read_f32s(n, components);
            let scale = normalization(attribute.data_type());
            if (shape.normalized || attribute.normalized()) && scale != 1.0 {
                values.iter_mut().for_each(|v| *v = (*v * scale).max(-1.0));
            }
            if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
                return Err(malformed(format!(
                    "{what}: {semantic} vertex {} is not finite (NaN or infinity)",
                    bad / components.max(1)
                )));
            }
            attributes.insert(accessor, (components, values));
        }

        let indices: Vec<u32> = mesh.faces().iter().flat_map(|f| f.map(|p| p.0)).collect();
        if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(malformed(format!("{what}: the Draco stream's index {bad} is out of range ({n} points)")));
        }
        if let Some(shape) = index_shape {
            if shape.count != indices.len() {
                return Err(malformed(format!(
                    "{what}: the indices accessor has {} elements, the Draco stream {} triangles ({} indices)",
                    shape.count,
                    indices.len() / 3,
                    indices.len()
                )));
            }
        }
        Ok(PrimitiveData { draco: Some(Decoded { attributes, indices }) })
    }

    /// A vertex attribute of a primitive (`components` per element): decoded from its Draco
    /// stream when the extension names it, else read from its accessor.
    pub(super) fn vertex_f32(
        &mut self,
        data: &PrimitiveData,
        accessor: usize,
        components: usize,
        what: &str,
    ) -> Result<Vec<f32>, SceneError> {
        match data.draco.as_ref().and_then(|d| d.attributes.get(&accessor)) {
            Some((dims, values)) if *dims == components => Ok(values.clone()),
            Some((dims, _)) => Err(malformed(format!(
                "{what}: accessor {accessor} has {dims} components per element, expected {components}"
            ))),
            None => self.buffers.read_f32(accessor, components, what),
        }
    }

    /// A primitive's indices: its Draco stream's faces, else its indices accessor (`None`
    /// without one: the vertices in order).
    pub(super) fn primitive_indices(
        &mut self,
        data: &PrimitiveData,
        prim: &gltf::json::mesh::Primitive,
        what: &str,
    ) -> Result<Option<Vec<u32>>, SceneError> {
        if let Some(d) = &data.draco {
            return Ok(Some(d.indices.clone()));
        }
        prim.indices.map(|a| self.buffers.read_indices(a.value(), &format!("{what} indices"))).transpose()
    }
}

/// The factor that maps a normalized integer of `t` to [-1, 1] or [0, 1], as glTF's accessors
/// do (the result clamped at -1); 1 for floats, which are never normalized.
fn normalization(t: DataType) -> f32 {
    match t {
        DataType::Int8 => 1.0 / 127.0,
        DataType::Uint8 => 1.0 / 255.0,
        DataType::Int16 => 1.0 / 32767.0,
        DataType::Uint16 => 1.0 / 65535.0,
        DataType::Int32 => 1.0 / i32::MAX as f32,
        DataType::Uint32 => 1.0 / u32::MAX as f32,
        _ => 1.0,
    }
}

#[cfg(test)]
#[path = "draco_tests.rs"]
mod tests;
