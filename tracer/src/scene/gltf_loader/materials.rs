//! glTF materials and their textures: factors, texture references and transforms, alpha
//! modes, and the images behind them (probed while loading, decoded at the end within the
//! scene's texel budget).

use super::*;

impl Loader<'_> {
    /// Our index of a glTF material (`None`: the glTF default material).
    pub(super) fn material(&mut self, index: Option<usize>) -> Result<u32, SceneError> {
        if let Some(&m) = self.material_map.get(&index) {
            return Ok(m);
        }
        let material = match index {
            None => Material::diffuse("default", Vec3::ONE),
            Some(i) => self.convert_material(i)?,
        };
        let id = self.materials.len() as u32;
        self.materials.push(material);
        self.material_map.insert(index, id);
        Ok(id)
    }

    pub(super) fn convert_material(&mut self, index: usize) -> Result<Material, SceneError> {
        let m = self.root.materials.get(index).ok_or_else(|| malformed(format!("material {index} does not exist")))?;
        let what = format!("material {index}");
        self.material_label = material_label(self.materials.len(), m.name.as_deref().unwrap_or_default());
        let [r, g, b, _alpha] = m.pbr_metallic_roughness.base_color_factor.0;
        let base_color = Vec3::new(r, g, b);
        if !base_color.is_finite() {
            return Err(malformed(format!("{what}: baseColorFactor is not finite")));
        }
        let base_color = base_color.clamp(Vec3::ZERO, Vec3::ONE);
        let strength =
            m.extensions.as_ref().and_then(|e| e.emissive_strength.as_ref()).map_or(1.0, |s| s.emissive_strength.0);
        let emission = Vec3::from(m.emissive_factor.0) * strength;
        if !emission.is_finite() || emission.min_element() < 0.0 {
            return Err(malformed(format!("{what}: emissiveFactor x emissive_strength must be finite and >= 0")));
        }
        if emission.max_element() > crate::scene::MAX_RADIANCE {
            return Err(malformed(format!(
                "{what}: emissiveFactor x emissive_strength = {emission} is above the largest radiance Lightport \
                 accepts ({:e})",
                crate::scene::MAX_RADIANCE
            )));
        }
        let (alpha, alpha_cutoff) = crate::scene::material_alpha::material_alpha(m, &what, &mut self.warnings)?;
        if let Some(ext) = &m.extensions {
            warn_extensions(&mut self.warnings, Some(&ext.others));
        }
        let label = |slot: &str| format!("{what} {slot}");
        let (base_color_texture, base_uv) =
            self.texture_info(m.pbr_metallic_roughness.base_color_texture.as_ref(), &label("baseColorTexture"))?;
        let (emissive_texture, emissive_uv) = if emission.max_element() > 0.0 {
            self.texture_info(m.emissive_texture.as_ref(), &label("emissiveTexture"))?
        } else {
            (None, UvTransform::default())
        };
        let pbr = &m.pbr_metallic_roughness;
        let (metallic, roughness) = (pbr.metallic_factor.0, pbr.roughness_factor.0);
        if !metallic.is_finite() || !roughness.is_finite() {
            return Err(malformed(format!("{what}: metallicFactor and roughnessFactor must be finite")));
        }
        let (metallic_roughness_texture, metal_rough_uv) =
            self.texture_info(pbr.metallic_roughness_texture.as_ref(), &label("metallicRoughnessTexture"))?;
        let (normal_texture, normal_scale, normal_uv) = match &m.normal_texture {
            Some(n) => {
                if !n.scale.is_finite() {
                    return Err(malformed(format!("{what}: normalTexture.scale is not finite")));
                }
                let others = n.extensions.as_ref().map(|e| &e.others);
                let (texture, uv) = self.texture_ref(n.index.value(), n.tex_coord, others, &label("normalTexture"))?;
                (texture, n.scale, uv)
            }
            None => (None, 1.0, UvTransform::default()),
        };
        let name = self.material_label.clone();
        let glass = self.glass(m, &name)?;
        Ok(Material {
            name: m.name.clone().unwrap_or_default(),
            base_color,
            base_color_texture,
            emission,
            emissive_texture,
            metallic: metallic.clamp(0.0, 1.0),
            roughness: roughness.clamp(0.0, 1.0),
            metallic_roughness_texture,
            normal_texture,
            normal_scale,
            alpha,
            alpha_cutoff,
            texture_uvs: [base_uv, emissive_uv, metal_rough_uv, normal_uv, glass.transmission_uv],
            transmission: glass.transmission,
            transmission_texture: glass.transmission_texture,
            ior: glass.ior,
            thickness: glass.thickness,
            attenuation_color: glass.attenuation_color,
            attenuation_distance: glass.attenuation_distance,
        })
    }

    /// `KHR_materials_transmission`, `KHR_materials_ior` and `KHR_materials_volume` of material
    /// `m` (`what` names it). A value outside the specification's range (transmission outside
    /// [0, 1], ior below 1, thickness or attenuation distance negative, a colour outside [0, 1],
    /// NaN or infinity where a finite number is due) is replaced by the specification's default
    /// with a warning naming the material, the value and the default; under `--strict` it is
    /// refused. `thicknessTexture` is not read (thickness only decides thin-walled or not).
    fn glass(&mut self, m: &gltf::json::Material, what: &str) -> Result<Glass, SceneError> {
        let ext = m.extensions.as_ref();
        let mut glass = Glass {
            transmission: 0.0,
            transmission_texture: None,
            transmission_uv: UvTransform::default(),
            ior: 1.5,
            thickness: 0.0,
            attenuation_color: Vec3::ONE,
            attenuation_distance: f32::INFINITY,
        };
        if let Some(t) = ext.and_then(|e| e.transmission.as_ref()) {
            let v = t.transmission_factor.0;
            glass.transmission = self.glass_value(what, "transmissionFactor", v, (0.0..=1.0).contains(&v), 0.0)?;
            let label = format!("{what} transmissionTexture");
            (glass.transmission_texture, glass.transmission_uv) =
                self.texture_info(t.transmission_texture.as_ref(), &label)?;
        }
        if let Some(i) = ext.and_then(|e| e.ior.as_ref()) {
            let v = i.ior.0;
            glass.ior = self.glass_value(what, "ior", v, v.is_finite() && v >= 1.0, 1.5)?;
        }
        if let Some(volume) = ext.and_then(|e| e.volume.as_ref()) {
            let v = volume.thickness_factor.0;
            glass.thickness = self.glass_value(what, "thicknessFactor", v, v.is_finite() && v >= 0.0, 0.0)?;
            let v = volume.attenuation_distance.0;
            glass.attenuation_distance = self.glass_value(what, "attenuationDistance", v, v > 0.0, f32::INFINITY)?;
            let c = Vec3::from(volume.attenuation_color.0);
            let ok = c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= 1.0;
            if !ok {
                let message = format!(
                    "{what}: KHR_materials_volume attenuationColor {c} is outside [0, 1]: the default [1, 1, 1] is \
                     used (no absorption)"
                );
                if self.strict {
                    return Err(malformed(message));
                }
                self.warnings.once(&format!("{what} attenuationColor"), || message);
            } else {
                glass.attenuation_color = c;
            }
        }
        Ok(glass)
    }

    /// `value` of glass parameter `name` when `ok`, else `default` with a warning naming the
    /// material, the parameter, the value and the default (an error under `--strict`).
    fn glass_value(&mut self, what: &str, name: &str, value: f32, ok: bool, default: f32) -> Result<f32, SceneError> {
        if ok {
            return Ok(value);
        }
        let message =
            format!("{what}: {name} {value} is outside the specification's range: the default {default} is used");
        if self.strict {
            return Err(malformed(message));
        }
        self.warnings.once(&format!("{what} {name}"), || message);
        Ok(default)
    }

    pub(super) fn texture_info(
        &mut self,
        info: Option<&gltf::json::texture::Info>,
        what: &str,
    ) -> Result<(Option<u32>, UvTransform), SceneError> {
        let Some(info) = info else {
            return Ok((None, UvTransform::default()));
        };
        let others = info.extensions.as_ref().map(|e| &e.others);
        self.texture_ref(info.index.value(), info.tex_coord, others, what)
    }

    /// Texture `index` as a textureInfo `what` reads it: on coordinate set `set` unless its
    /// `KHR_texture_transform` overrides it, transformed by it. Sets beyond `TEXCOORD_1` drop
    /// the texture (warned); a transform that is not finite refuses the file.
    pub(super) fn texture_ref(
        &mut self,
        index: usize,
        set: u32,
        extensions: Option<&Map<String, Value>>,
        what: &str,
    ) -> Result<(Option<u32>, UvTransform), SceneError> {
        warn_extensions(&mut self.warnings, extensions);
        let uv = texture_ref::parse_gltf(set, extensions.and_then(|e| e.get("KHR_texture_transform")), what)
            .map_err(malformed)?;
        if uv.texcoord >= texture_ref::TEXCOORD_SETS {
            let set = uv.texcoord;
            self.warnings.once("texture coordinate sets", || {
                format!("textures on TEXCOORD_{set} are not supported (only TEXCOORD_0 and TEXCOORD_1): those textures are dropped ({what})")
            });
            return Ok((None, UvTransform::default()));
        }
        Ok((self.texture(index)?, uv))
    }

    /// A primitive's `TEXCOORD_<set>` accessor read and checked against its vertex count.
    pub(super) fn texcoords(
        &mut self,
        data: &PrimitiveData,
        accessor: Option<usize>,
        set: u32,
        vertex_count: usize,
        what: &str,
    ) -> Result<Option<Vec<Vec2>>, SceneError> {
        let Some(a) = accessor else { return Ok(None) };
        let t = to_vec2(self.vertex_f32(data, a, 2, &format!("{what} TEXCOORD_{set}"))?);
        if t.len() != vertex_count {
            return Err(malformed(format!("{what}: TEXCOORD_{set} has {} elements, POSITION {vertex_count}", t.len())));
        }
        Ok(Some(t))
    }

    /// A material that was copied without its `TEXCOORD_1` textures and that no triangle uses
    /// any more loses them too, so that it does not ask for the second UV set for nothing.
    pub(super) fn drop_unused_texcoord1_textures(&mut self) {
        if self.without_texcoord1.is_empty() {
            return;
        }
        let mut used = vec![false; self.materials.len()];
        for t in self.triangles.iter().chain(self.instanced_meshes.iter().flat_map(|m| &m.triangles)) {
            if let Some(u) = used.get_mut(t.material as usize) {
                *u = true;
            }
        }
        for &m in self.without_texcoord1.keys() {
            if let Some(material) = self.materials.get_mut(m as usize).filter(|_| !used[m as usize]) {
                texture_ref::drop_texcoord1_textures(material);
            }
        }
    }

    /// `material` without the textures it reads on `TEXCOORD_1`, for a primitive `what` that
    /// has no such set (warned; one copy per material).
    pub(super) fn material_without_texcoord1(&mut self, material: u32, what: &str) -> u32 {
        let name = self.materials.get(material as usize).map_or(String::new(), |m| m.name.clone());
        self.warnings.once(&format!("no TEXCOORD_1 {material}"), || {
            format!("{what} has no TEXCOORD_1, which material {material} ({name:?}) reads textures on: there they are ignored")
        });
        if let Some(&m) = self.without_texcoord1.get(&material) {
            return m;
        }
        let Some(mut copy) = self.materials.get(material as usize).cloned() else { return material };
        texture_ref::drop_texcoord1_textures(&mut copy);
        self.materials.push(copy);
        let id = self.materials.len() as u32 - 1;
        self.without_texcoord1.insert(material, id);
        id
    }

    pub(super) fn texture(&mut self, index: usize) -> Result<Option<u32>, SceneError> {
        if let Some(&t) = self.texture_map.get(&index) {
            if let Some(&problem) = self.texture_problems.get(&index) {
                self.problems.used_by(problem, &self.material_label);
            }
            return Ok(t);
        }
        let tex = self.root.textures.get(index).ok_or_else(|| malformed(format!("texture {index} does not exist")))?;
        if let Some(ext) = &tex.extensions {
            warn_extensions(&mut self.warnings, Some(&ext.others));
        }
        let (wrap_s, wrap_t) = match tex.sampler {
            None => (Wrap::Repeat, Wrap::Repeat),
            Some(s) => {
                let sampler = self
                    .root
                    .samplers
                    .get(s.value())
                    .ok_or_else(|| malformed(format!("sampler {} does not exist", s.value())))?;
                (wrap(sampler.wrap_s), wrap(sampler.wrap_t))
            }
        };
        // EXT_texture_webp's image is preferred to the core one (a fallback), as the extension asks.
        let webp = tex.extensions.as_ref().and_then(|e| e.others.get("EXT_texture_webp"));
        let webp_source = match webp.and_then(|w| w.get("source")) {
            None => None,
            Some(source) => {
                Some(source.as_u64().map(|s| s as usize).filter(|&s| s < self.root.images.len()).ok_or_else(|| {
                    malformed(format!("texture {index}: EXT_texture_webp source {source} is not an image"))
                })?)
            }
        };
        if webp_source.is_none() && tex.source.value() == u32::MAX as usize {
            // No core source: the image is only given by an extension Lightport does not read (KTX2, ...).
            self.warnings.once("texture without a source", || {
                "textures whose image is only provided by an extension are dropped".into()
            });
            self.texture_map.insert(index, None);
            return Ok(None);
        }
        let image = webp_source.unwrap_or(tex.source.value());
        let result = match self.images.get(&image).copied() {
            // Probed before for another glTF texture: share it, or copy it for other wrap modes.
            Some(Some(first)) => match self.textures.get(first as usize) {
                Some(t) if (t.wrap_s, t.wrap_t) == (wrap_s, wrap_t) => Some(first),
                Some(t) => {
                    let image = t.image;
                    let texels = self.probed.get(image).map_or(0, |(_, header)| header.texels());
                    if texels > self.texel_budget()? {
                        return Err(texel_budget_error());
                    }
                    self.textures.push(PendingTexture { image, wrap_s, wrap_t });
                    Some(self.textures.len() as u32 - 1)
                }
                None => None,
            },
            Some(None) => {
                if let Some(&problem) = self.image_problems.get(&image) {
                    self.problems.used_by(problem, &self.material_label);
                    self.texture_problems.insert(index, problem);
                }
                None
            }
            None => {
                let probed = self.probe_image(image)?;
                if let Some(&problem) = self.image_problems.get(&image) {
                    self.texture_problems.insert(index, problem);
                }
                let id = probed.map(|image| {
                    self.textures.push(PendingTexture { image, wrap_s, wrap_t });
                    self.textures.len() as u32 - 1
                });
                self.images.insert(image, id);
                id
            }
        };
        self.texture_map.insert(index, result);
        Ok(result)
    }

    /// Texels the scene's textures may still add.
    pub(super) fn texel_budget(&self) -> Result<u64, SceneError> {
        let used: u64 = self.textures.iter().filter_map(|t| self.probed.get(t.image)).map(|(_, h)| h.texels()).sum();
        match MAX_SCENE_TEXELS.checked_sub(used) {
            Some(left) if left > 0 => Ok(left),
            _ => Err(texel_budget_error()),
        }
    }

    /// Decodes the textures (all images probed), in parallel, into one shared atlas. Images
    /// that do not decode are dropped with a warning unless loading is strict.
    pub(super) fn decode_textures(&mut self) -> Result<Vec<crate::scene::Texture>, SceneError> {
        let images = self
            .probed
            .iter()
            .map(|(source, header)| {
                let bytes = match source {
                    ImageSource::View(view) => self.buffers.loaded_view(*view)?.0,
                    ImageSource::Bytes(bytes) => bytes.as_slice(),
                };
                Ok((bytes, header))
            })
            .collect::<Result<Vec<_>, SceneError>>()?;
        let textures = std::mem::take(&mut self.textures);
        decode_textures_forgiving(&images, textures, &mut self.materials, &mut self.problems, self.strict)
    }

    /// Reads image `index` and its header (decoded later, with the others: see
    /// [`Loader::decode_textures`]); its index in `probed`. `None` (warned) when its format is
    /// not supported, or (unless loading is strict) its file is missing or unreadable or its
    /// header does not decode.
    pub(super) fn probe_image(&mut self, index: usize) -> Result<Option<usize>, SceneError> {
        let budget = self.texel_budget()?;
        let json = self.root.images.get(index).ok_or_else(|| malformed(format!("image {index} does not exist")))?;
        let name = match &json.uri {
            Some(uri) if !uri.starts_with("data:") => format!("{index} ({uri})"),
            _ => index.to_string(),
        };
        let probed = match (&json.buffer_view, &json.uri) {
            (Some(view), _) => {
                let (bytes, _) = self.buffers.view(view.value())?;
                probe_srgb(bytes, &name, budget).map(|p| (p, ImageSource::View(view.value())))
            }
            (None, Some(uri)) => read_uri(uri, self.base_dir, &format!("image {name}"))
                .and_then(|bytes| Ok((probe_srgb(&bytes, &name, budget)?, ImageSource::Bytes(bytes)))),
            (None, None) => return Err(malformed(format!("image {index} has neither a uri nor a bufferView"))),
        };
        let (probed, source) = match probed {
            Ok(p) => p,
            Err(e) if !self.strict && is_texture_problem(&e) => {
                let problem = self.problems.add(format!("image {name}"), &e);
                self.problems.used_by(problem, &self.material_label);
                self.image_problems.insert(index, problem);
                return Ok(None);
            }
            Err(e) => return Err(e),
        };
        match probed {
            Probed::Image(header) => {
                self.probed.push((source, header));
                Ok(Some(self.probed.len() - 1))
            }
            Probed::Unsupported(format) => {
                let key = format!("image format {format}");
                self.warnings.once(&key, || {
                    format!(
                        "image format {format} is not supported (PNG, JPEG and WebP are): textures using it are dropped"
                    )
                });
                Ok(None)
            }
        }
    }
}

/// Where a probed image's bytes are.
pub(super) enum ImageSource {
    /// In a buffer view (loaded in `Buffers`).
    View(usize),
    /// Read from a file or a data URI.
    Bytes(Vec<u8>),
}

pub(super) fn texel_budget_error() -> SceneError {
    SceneError::TooLarge(format!("the scene's textures have more than {MAX_SCENE_TEXELS} texels"))
}

pub(super) fn wrap(mode: Checked<WrappingMode>) -> Wrap {
    match mode {
        Checked::Valid(WrappingMode::ClampToEdge) => Wrap::ClampToEdge,
        Checked::Valid(WrappingMode::MirroredRepeat) => Wrap::MirroredRepeat,
        _ => Wrap::Repeat,
    }
}

/// A material's glass parameters as the glTF extensions give them (checked).
struct Glass {
    transmission: f32,
    transmission_texture: Option<u32>,
    transmission_uv: UvTransform,
    ior: f32,
    thickness: f32,
    attenuation_color: Vec3,
    attenuation_distance: f32,
}
