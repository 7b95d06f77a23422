//! glTF buffers and accessors, decoded by hand so that every offset, stride and count is checked
//! against the bytes that back it before anything is allocated.

use std::borrow::Cow;
use std::path::Path;

use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;
use gltf::json::Root;

use super::util::read_uri;
use super::SceneError;

/// Most elements one accessor may have.
const MAX_ACCESSOR_COUNT: u64 = 1 << 26;
/// Most elements of an accessor without a bufferView (zeros, maybe with sparse values): nothing
/// in the file backs its count, so it gets a tighter cap of its own.
const MAX_UNBACKED_COUNT: usize = 1 << 22;

fn malformed(m: String) -> SceneError {
    SceneError::Malformed(m)
}

/// The buffers of a glTF file, loaded on first use (so a missing buffer that holds only, say,
/// animation data does not stop a scene from loading).
pub(crate) struct Buffers<'a> {
    root: &'a Root,
    base_dir: Option<&'a Path>,
    bin: Option<&'a [u8]>,
    loaded: Vec<Option<Cow<'a, [u8]>>>,
}

impl<'a> Buffers<'a> {
    pub(crate) fn new(root: &'a Root, base_dir: Option<&'a Path>, bin: Option<&'a [u8]>) -> Self {
        Self { root, base_dir, bin, loaded: (0..root.buffers.len()).map(|_| None).collect() }
    }

    /// The bytes of buffer `index`, at least `byteLength` long.
    pub(crate) fn buffer(&mut self, index: usize) -> Result<&[u8], SceneError> {
        let json = self.root.buffers.get(index).ok_or_else(|| malformed(format!("buffer {index} does not exist")))?;
        let slot = self.loaded.get_mut(index).ok_or_else(|| malformed(format!("buffer {index} does not exist")))?;
        if slot.is_none() {
            let what = format!("buffer {index}");
            let data: Cow<'a, [u8]> =
                match &json.uri {
                    Some(uri) => Cow::Owned(read_uri(uri, self.base_dir, &what)?),
                    None => Cow::Borrowed(self.bin.ok_or_else(|| {
                        malformed(format!("buffer {index} has no uri and there is no GLB binary chunk"))
                    })?),
                };
            let declared = json.byte_length.0;
            if (data.len() as u64) < declared {
                return Err(malformed(format!(
                    "buffer {index} is truncated: {} bytes, but byteLength is {declared}",
                    data.len()
                )));
            }
            *slot = Some(data);
        }
        Ok(slot.as_deref().unwrap_or(&[]))
    }

    /// The bytes of buffer view `index` and its byte stride (if it declares one).
    pub(crate) fn view(&mut self, index: usize) -> Result<(&[u8], Option<usize>), SceneError> {
        let view =
            self.root.buffer_views.get(index).ok_or_else(|| malformed(format!("bufferView {index} does not exist")))?;
        self.buffer(view.buffer.value())?;
        self.loaded_view(index)
    }

    /// [`Buffers::view`] of a view whose buffer is loaded already (by an earlier `view`).
    pub(crate) fn loaded_view(&self, index: usize) -> Result<(&[u8], Option<usize>), SceneError> {
        let view =
            self.root.buffer_views.get(index).ok_or_else(|| malformed(format!("bufferView {index} does not exist")))?;
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let length = view.byte_length.0;
        let stride = view.byte_stride.map(|s| s.0);
        let buffer = self
            .loaded
            .get(view.buffer.value())
            .and_then(|b| b.as_deref())
            .ok_or_else(|| malformed(format!("buffer {} is not loaded", view.buffer.value())))?;
        let end = offset
            .checked_add(length)
            .ok_or_else(|| malformed(format!("bufferView {index}: offset + length overflows")))?;
        let bytes = usize::try_from(offset)
            .ok()
            .zip(usize::try_from(end).ok())
            .and_then(|(o, e)| buffer.get(o..e))
            .ok_or_else(|| {
                malformed(format!(
                    "bufferView {index} (bytes {offset}..{end}) extends past the end of buffer {} ({} bytes)",
                    view.buffer.value(),
                    buffer.len()
                ))
            })?;
        Ok((bytes, stride))
    }

    /// Reads a float accessor with `components` components per element (VEC2/VEC3...),
    /// converting normalized and (KHR_mesh_quantization) integer components to f32.
    pub(crate) fn read_f32(&mut self, index: usize, components: usize, what: &str) -> Result<Vec<f32>, SceneError> {
        let layout = self.layout(index, what)?;
        if layout.dims != components {
            return Err(malformed(format!(
                "{what}: accessor {index} has {} components per element, expected {components}",
                layout.dims
            )));
        }
        let ct = layout.component_type;
        let normalized = layout.normalized;
        let out = self.decode(&layout, what, |bytes| component_f32(bytes, ct, normalized))?;
        if let Some(bad) = out.iter().position(|v| !v.is_finite()) {
            return Err(malformed(format!(
                "{what}: accessor {index} element {} is not finite (NaN or infinity)",
                bad / components.max(1)
            )));
        }
        Ok(out)
    }

    /// Reads an index accessor (SCALAR of unsigned byte/short/int).
    pub(crate) fn read_indices(&mut self, index: usize, what: &str) -> Result<Vec<u32>, SceneError> {
        let layout = self.layout(index, what)?;
        if layout.dims != 1 {
            return Err(malformed(format!("{what}: index accessor {index} is not SCALAR")));
        }
        let ct = layout.component_type;
        if !matches!(ct, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) {
            return Err(malformed(format!(
                "{what}: index accessor {index} has component type {ct:?}, expected an unsigned integer"
            )));
        }
        self.decode(&layout, what, |bytes| component_u32(bytes, ct))
    }

    /// An accessor's shape (components per element, element count, component type, normalized),
    /// checked as for reading it: for data that replaces the accessor's own (Draco).
    pub(crate) fn shape(&self, index: usize, what: &str) -> Result<Shape, SceneError> {
        let l = self.layout(index, what)?;
        Ok(Shape { dims: l.dims, count: l.count, normalized: l.normalized })
    }

    /// Resolves an accessor's layout, checking its type.
    fn layout(&self, index: usize, what: &str) -> Result<Layout, SceneError> {
        let acc = self
            .root
            .accessors
            .get(index)
            .ok_or_else(|| malformed(format!("{what}: accessor {index} does not exist")))?;
        let dims = match acc.type_ {
            Checked::Valid(Type::Scalar) => 1,
            Checked::Valid(Type::Vec2) => 2,
            Checked::Valid(Type::Vec3) => 3,
            Checked::Valid(Type::Vec4) => 4,
            // Skins' inverse bind matrices; a MAT4's columns need no padding for any component type.
            Checked::Valid(Type::Mat4) => 16,
            Checked::Valid(t) => return Err(malformed(format!("{what}: accessor {index} has matrix type {t:?}"))),
            Checked::Invalid => return Err(malformed(format!("{what}: accessor {index} has an invalid type"))),
        };
        let component_type = match acc.component_type {
            Checked::Valid(c) => c.0,
            Checked::Invalid => {
                return Err(malformed(format!("{what}: accessor {index} has an invalid componentType")))
            }
        };
        let count = acc.count.0;
        if count > MAX_ACCESSOR_COUNT {
            return Err(SceneError::TooLarge(format!(
                "{what}: accessor {index} has {count} elements (limit {MAX_ACCESSOR_COUNT})"
            )));
        }
        let sparse = match &acc.sparse {
            None => None,
            Some(s) => {
                let ict = match s.indices.component_type {
                    Checked::Valid(c) => c.0,
                    Checked::Invalid => {
                        return Err(malformed(format!(
                            "{what}: accessor {index} sparse indices have an invalid componentType"
                        )))
                    }
                };
                Some(SparseLayout {
                    count: s.count.0,
                    indices_view: s.indices.buffer_view.value(),
                    indices_offset: s.indices.byte_offset.0,
                    indices_type: ict,
                    values_view: s.values.buffer_view.value(),
                    values_offset: s.values.byte_offset.0,
                })
            }
        };
        Ok(Layout {
            index,
            dims,
            component_type,
            normalized: acc.normalized,
            count: count as usize,
            view: acc.buffer_view.map(|v| v.value()),
            offset: acc.byte_offset.map_or(0, |o| o.0),
            sparse,
        })
    }

    /// Decodes every element of an accessor (dense data, then sparse substitutions).
    fn decode<T: Copy + Default>(
        &mut self,
        l: &Layout,
        what: &str,
        component: impl Fn(&[u8]) -> Option<T>,
    ) -> Result<Vec<T>, SceneError> {
        let csize = l.component_type.size();
        let elem = csize * l.dims;
        let index = l.index;
        let mut out: Vec<T>;
        match l.view {
            Some(view_index) => {
                let (bytes, stride) = self.view(view_index)?;
                let stride = stride.unwrap_or(elem);
                if stride < elem {
                    return Err(malformed(format!(
                        "{what}: accessor {index} elements ({elem} bytes) are larger than the byteStride {stride}"
                    )));
                }
                let needed = if l.count == 0 {
                    Some(0u64)
                } else {
                    (l.count as u64 - 1)
                        .checked_mul(stride as u64)
                        .and_then(|v| v.checked_add(elem as u64))
                        .and_then(|v| v.checked_add(l.offset))
                };
                match needed {
                    Some(n) if n <= bytes.len() as u64 => {}
                    _ => {
                        return Err(malformed(format!(
                            "{what}: accessor {index} ({} elements of {elem} bytes, stride {stride}, offset {}) extends past the end of bufferView {view_index} ({} bytes)",
                            l.count,
                            l.offset,
                            bytes.len()
                        )))
                    }
                }
                let offset = l.offset as usize;
                out = Vec::with_capacity(l.count * l.dims);
                for i in 0..l.count {
                    let base = offset + i * stride;
                    for c in 0..l.dims {
                        let at = base + c * csize;
                        let v = bytes
                            .get(at..at + csize)
                            .and_then(&component)
                            .ok_or_else(|| malformed(format!("{what}: accessor {index} element {i} is unreadable")))?;
                        out.push(v);
                    }
                }
            }
            None => {
                // glTF: an accessor without a bufferView holds zeros (plus sparse values).
                if l.count > MAX_UNBACKED_COUNT {
                    return Err(SceneError::TooLarge(format!(
                        "{what}: accessor {index} without a bufferView has {} elements (limit {MAX_UNBACKED_COUNT})",
                        l.count
                    )));
                }
                out = vec![T::default(); l.count * l.dims];
            }
        }
        if let Some(s) = &l.sparse {
            self.apply_sparse(l, s, what, &mut out, &component)?;
        }
        Ok(out)
    }

    fn apply_sparse<T: Copy>(
        &mut self,
        l: &Layout,
        s: &SparseLayout,
        what: &str,
        out: &mut [T],
        component: &impl Fn(&[u8]) -> Option<T>,
    ) -> Result<(), SceneError> {
        let index = l.index;
        if s.count == 0 || s.count > l.count as u64 {
            return Err(malformed(format!(
                "{what}: accessor {index} has {} sparse elements for {} elements",
                s.count, l.count
            )));
        }
        if !matches!(s.indices_type, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) {
            return Err(malformed(format!("{what}: accessor {index} sparse indices are not unsigned integers")));
        }
        let count = s.count as usize;
        let isize = s.indices_type.size();
        let indices: Vec<u32> = {
            let (bytes, _) = self.view(s.indices_view)?;
            let start = usize::try_from(s.indices_offset).unwrap_or(usize::MAX);
            let region = start.checked_add(count * isize).and_then(|end| bytes.get(start..end)).ok_or_else(|| {
                malformed(format!("{what}: accessor {index} sparse indices extend past their bufferView"))
            })?;
            region.chunks_exact(isize).filter_map(|c| component_u32(c, s.indices_type)).collect()
        };
        let csize = l.component_type.size();
        let elem = csize * l.dims;
        let (bytes, _) = self.view(s.values_view)?;
        let start = usize::try_from(s.values_offset).unwrap_or(usize::MAX);
        let region = start
            .checked_add(count * elem)
            .and_then(|end| bytes.get(start..end))
            .ok_or_else(|| malformed(format!("{what}: accessor {index} sparse values extend past their bufferView")))?;
        for (k, &target) in indices.iter().enumerate() {
            let target = target as usize;
            if target >= l.count {
                return Err(malformed(format!(
                    "{what}: accessor {index} sparse index {target} is out of range ({} elements)",
                    l.count
                )));
            }
            for c in 0..l.dims {
                let at = k * elem + c * csize;
                let v = region
                    .get(at..at + csize)
                    .and_then(component)
                    .ok_or_else(|| malformed(format!("{what}: accessor {index} sparse value {k} is unreadable")))?;
                if let Some(slot) = out.get_mut(target * l.dims + c) {
                    *slot = v;
                }
            }
        }
        Ok(())
    }
}

/// What [`Buffers::shape`] tells of an accessor.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Shape {
    /// Components per element (1 for SCALAR ... 16 for MAT4).
    pub(crate) dims: usize,
    /// Elements.
    pub(crate) count: usize,
    /// Integer components map to [0, 1] or [-1, 1].
    pub(crate) normalized: bool,
}

struct Layout {
    index: usize,
    dims: usize,
    component_type: ComponentType,
    normalized: bool,
    count: usize,
    view: Option<usize>,
    offset: u64,
    sparse: Option<SparseLayout>,
}

struct SparseLayout {
    count: u64,
    indices_view: usize,
    indices_offset: u64,
    indices_type: ComponentType,
    values_view: usize,
    values_offset: u64,
}

fn component_f32(b: &[u8], ct: ComponentType, normalized: bool) -> Option<f32> {
    Some(match ct {
        ComponentType::F32 => f32::from_le_bytes(b.try_into().ok()?),
        ComponentType::I8 => {
            let v = i8::from_le_bytes(b.try_into().ok()?) as f32;
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U8 => {
            let v = u8::from_le_bytes(b.try_into().ok()?) as f32;
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes(b.try_into().ok()?) as f32;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes(b.try_into().ok()?) as f32;
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        ComponentType::U32 => {
            let v = u32::from_le_bytes(b.try_into().ok()?) as f32;
            if normalized {
                v / u32::MAX as f32
            } else {
                v
            }
        }
    })
}

fn component_u32(b: &[u8], ct: ComponentType) -> Option<u32> {
    Some(match ct {
        ComponentType::U8 => u32::from(*b.first()?),
        ComponentType::U16 => u32::from(u16::from_le_bytes(b.try_into().ok()?)),
        ComponentType::U32 => u32::from_le_bytes(b.try_into().ok()?),
        _ => return None,
    })
}
