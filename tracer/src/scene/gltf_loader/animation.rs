//! glTF animations: the chosen animation's node channels (translation, rotation, scale)
//! sampled at one time, as the node transforms the scene is flattened with. Interpolation as
//! the specification defines it: STEP, LINEAR (rotations by spherical interpolation) and
//! CUBICSPLINE (Hermite, tangents scaled by the keyframe interval); before the first keyframe
//! the first value, after the last the last. A `weights` channel animates a mesh's morph
//! target weights (`morph.rs`).

use super::*;

/// Which animation poses the scene ([`LoadOptions::animation`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum AnimationChoice {
    /// The file's first animation, as a viewer plays it by default (the rest pose without one).
    #[default]
    First,
    /// The nodes' own transforms, whatever the animations.
    Rest,
    /// The animation of this name, or else of this index.
    Named(String),
}

/// A node's animated transform components; `None` keeps the node's own.
#[derive(Clone, Debug, Default)]
pub(super) struct NodePose {
    translation: Option<Vec3>,
    rotation: Option<Quat>,
    scale: Option<Vec3>,
    /// Morph target weights (`morph.rs`).
    pub(super) weights: Option<Vec<f32>>,
}

impl NodePose {
    /// The node's local matrix with the animated components in place of its own.
    pub(super) fn matrix(&self, node: &gltf::json::scene::Node) -> Mat4 {
        self.local(&RestTransform::of(node))
    }

    /// Whether it animates the node's transform (a translation, rotation or scale: not only
    /// its morph weights).
    pub(super) fn transforms(&self) -> bool {
        self.translation.is_some() || self.rotation.is_some() || self.scale.is_some()
    }

    /// The local matrix of a node at rest `rest` with the animated components in its place.
    pub(super) fn local(&self, rest: &RestTransform) -> Mat4 {
        let t = self.translation.unwrap_or(rest.translation);
        let s = self.scale.unwrap_or(rest.scale);
        let q = self.rotation.unwrap_or(rest.rotation);
        let len = q.length();
        let q = if len > 0.0 && len.is_finite() { q / len } else { Quat::IDENTITY };
        Mat4::from_scale_rotation_translation(s, q, t)
    }
}

/// A node's own transform components, which channels override (the rest pose).
#[derive(Clone, Copy, Debug)]
pub(super) struct RestTransform {
    pub(super) translation: Vec3,
    pub(super) rotation: Quat,
    pub(super) scale: Vec3,
}

impl RestTransform {
    pub(super) fn of(node: &gltf::json::scene::Node) -> Self {
        RestTransform {
            translation: Vec3::from(node.translation.unwrap_or([0.0; 3])),
            rotation: node.rotation.map_or(Quat::IDENTITY, |r| Quat::from_array(r.0)),
            scale: Vec3::from(node.scale.unwrap_or([1.0; 3])),
        }
    }
}

/// Interpolation of a sampler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// Keyframes of one channel: times and, per keyframe, one value (STEP, LINEAR) or an
/// in-tangent, a value and an out-tangent (CUBICSPLINE), each of `n` components.
#[derive(Clone, Debug)]
pub(super) struct Keyframes {
    pub(super) times: Vec<f32>,
    pub(super) values: Vec<f32>,
    pub(super) n: usize,
    pub(super) interpolation: Interpolation,
}

impl Keyframes {
    fn element(&self, k: usize, part: usize) -> &[f32] {
        let stride = if self.interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        let at = (k * stride + part) * self.n;
        &self.values[at..at + self.n]
    }

    /// The value at `time` (components as stored; rotations still to normalise, except LINEAR's
    /// slerp when `rotation`).
    fn sample(&self, time: f32, rotation: bool) -> Vec<f32> {
        let value = if self.interpolation == Interpolation::CubicSpline { 1 } else { 0 };
        let last = self.times.len() - 1;
        if time <= self.times[0] {
            return self.element(0, value).to_vec();
        }
        if time >= self.times[last] {
            return self.element(last, value).to_vec();
        }
        // The segment [k, k + 1] holding `time` (times are non-decreasing).
        let k = self.times.partition_point(|&t| t <= time) - 1;
        let dt = self.times[k + 1] - self.times[k];
        let u = if dt > 0.0 { (time - self.times[k]) / dt } else { 0.0 };
        match self.interpolation {
            Interpolation::Step => self.element(k, 0).to_vec(),
            Interpolation::Linear if rotation => {
                let a = Quat::from_slice(self.element(k, 0)).normalize();
                let b = Quat::from_slice(self.element(k + 1, 0)).normalize();
                a.slerp(b, u).to_array().to_vec()
            }
            Interpolation::Linear => {
                let (a, b) = (self.element(k, 0), self.element(k + 1, 0));
                a.iter().zip(b).map(|(a, b)| a + (b - a) * u).collect()
            }
            Interpolation::CubicSpline => {
                let (u2, u3) = (u * u, u * u * u);
                let (h00, h10, h01, h11) =
                    (2.0 * u3 - 3.0 * u2 + 1.0, u3 - 2.0 * u2 + u, -2.0 * u3 + 3.0 * u2, u3 - u2);
                let (v0, b0) = (self.element(k, 1), self.element(k, 2));
                let (a1, v1) = (self.element(k + 1, 0), self.element(k + 1, 1));
                (0..self.n).map(|i| h00 * v0[i] + h10 * dt * b0[i] + h01 * v1[i] + h11 * dt * a1[i]).collect()
            }
        }
    }
}

/// What a channel animates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Target {
    Translation,
    Rotation,
    Scale,
    Weights,
}

/// One channel of the chosen animation: a node's component and its keyframes.
#[derive(Clone, Debug)]
pub(super) struct Channel {
    pub(super) node: usize,
    pub(super) target: Target,
    pub(super) keys: Keyframes,
}

impl Channel {
    /// The time of the channel's last keyframe.
    pub(super) fn end(&self) -> f32 {
        self.keys.times.last().copied().unwrap_or(0.0)
    }
}

/// The node transforms `channels` give at `time` (a finite number of seconds).
pub(super) fn pose_at(channels: &[Channel], time: f32) -> HashMap<usize, NodePose> {
    let mut pose: HashMap<usize, NodePose> = HashMap::new();
    for channel in channels {
        let v = channel.keys.sample(time, channel.target == Target::Rotation);
        let entry = pose.entry(channel.node).or_default();
        match channel.target {
            Target::Translation => entry.translation = Some(Vec3::from_slice(&v)),
            Target::Scale => entry.scale = Some(Vec3::from_slice(&v)),
            Target::Weights => entry.weights = Some(v),
            Target::Rotation => entry.rotation = Some(Quat::from_slice(&v)),
        }
    }
    pose
}

impl Loader<'_> {
    /// The channels of `choice` (none for the rest pose or a file without animations), checked,
    /// and the chosen animation's name (empty without one).
    pub(super) fn channels(
        &mut self,
        animations: &[Value],
        choice: &AnimationChoice,
    ) -> Result<(Vec<Channel>, String), SceneError> {
        let index = match choice {
            AnimationChoice::Rest => return Ok((Vec::new(), String::new())),
            AnimationChoice::First if animations.is_empty() => return Ok((Vec::new(), String::new())),
            AnimationChoice::First => 0,
            AnimationChoice::Named(name) => {
                let by_name = animations.iter().position(|a| a.get("name").and_then(Value::as_str) == Some(name));
                match by_name.or_else(|| name.parse::<usize>().ok().filter(|&i| i < animations.len())) {
                    Some(i) => i,
                    None => {
                        let names: Vec<String> = animations
                            .iter()
                            .enumerate()
                            .map(|(i, a)| a.get("name").and_then(Value::as_str).map_or(i.to_string(), str::to_owned))
                            .collect();
                        return Err(malformed(format!(
                            "no animation named or numbered \"{name}\" (the file has {}: {})",
                            animations.len(),
                            if names.is_empty() { "none".to_owned() } else { names.join(", ") }
                        )));
                    }
                }
            }
        };
        let animation = &animations[index];
        let what = format!("animation {index}");
        let list = |key: &str| animation.get(key).and_then(Value::as_array).map(Vec::as_slice).unwrap_or(&[]);
        let (channels, samplers) = (list("channels"), list("samplers"));
        let mut out = Vec::new();
        for (c, channel) in channels.iter().enumerate() {
            let what = format!("{what} channel {c}");
            let target = channel.get("target");
            let Some(node) = target.and_then(|t| t.get("node")).and_then(Value::as_u64) else { continue };
            let node = usize::try_from(node).unwrap_or(usize::MAX);
            let gltf_node =
                self.root.nodes.get(node).ok_or_else(|| malformed(format!("{what}: node {node} does not exist")))?;
            let path = target.and_then(|t| t.get("path")).and_then(Value::as_str).unwrap_or("");
            let (target, n) = match path {
                "translation" => (Target::Translation, 3),
                "scale" => (Target::Scale, 3),
                "rotation" => (Target::Rotation, 4),
                "weights" => match self.morph_target_count(gltf_node)? {
                    0 => continue,
                    targets => (Target::Weights, targets),
                },
                other => return Err(malformed(format!("{what}: unknown target path \"{other}\""))),
            };
            if gltf_node.matrix.is_some() && target != Target::Weights {
                self.warnings.once("animated matrix", || {
                    "an animation targets a node given by a matrix (glTF allows only TRS nodes): that channel is ignored"
                        .into()
                });
                continue;
            }
            let keys = self.keyframes(samplers, channel, n, &what)?;
            out.push(Channel { node, target, keys });
        }
        let name = animation.get("name").and_then(Value::as_str).unwrap_or_default().to_owned();
        Ok((out, name))
    }

    /// The keyframes of `channel`'s sampler, checked: times non-decreasing, as many values as
    /// the interpolation needs.
    fn keyframes(
        &mut self,
        samplers: &[Value],
        channel: &Value,
        n: usize,
        what: &str,
    ) -> Result<Keyframes, SceneError> {
        let index = |v: Option<&Value>, name: &str| {
            v.and_then(Value::as_u64)
                .and_then(|i| usize::try_from(i).ok())
                .ok_or_else(|| malformed(format!("{what}: no {name}")))
        };
        let s = index(channel.get("sampler"), "sampler")?;
        let sampler = samplers.get(s).ok_or_else(|| malformed(format!("{what}: sampler {s} does not exist")))?;
        let interpolation = match sampler.get("interpolation").and_then(Value::as_str).unwrap_or("LINEAR") {
            "LINEAR" => Interpolation::Linear,
            "STEP" => Interpolation::Step,
            "CUBICSPLINE" => Interpolation::CubicSpline,
            other => return Err(malformed(format!("{what}: unknown interpolation \"{other}\""))),
        };
        let (input, output) = (index(sampler.get("input"), "input")?, index(sampler.get("output"), "output")?);
        for a in [input, output] {
            if a >= self.root.accessors.len() {
                return Err(malformed(format!("{what}: accessor {a} does not exist")));
            }
        }
        let times = self.buffers.read_f32(input, 1, &format!("{what} input"))?;
        let values = self.buffers.read_f32(output, n, &format!("{what} output"))?;
        if times.is_empty() {
            return Err(malformed(format!("{what}: no keyframes")));
        }
        if times.windows(2).any(|w| w[1] < w[0]) {
            return Err(malformed(format!("{what}: keyframe times decrease")));
        }
        let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        if values.len() != times.len() * per_key * n {
            return Err(malformed(format!(
                "{what}: {} keyframes need {} output elements ({interpolation:?}), the accessor has {}",
                times.len(),
                times.len() * per_key,
                values.len() / n
            )));
        }
        Ok(Keyframes { times, values, n, interpolation })
    }
}
