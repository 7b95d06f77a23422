#[kernel_dsl::kernel]
pub mod instances {
    //! Two-level scenes (`Features::instances`): a top-level BVH over instances, each a bottom
    //! level (a mesh's own BVH, in the mesh's space) placed by an affine transform. Traversal
    //! (`kernel::traverse`) walks both levels in one loop with one stack: at a top-level leaf it
    //! moves the ray into the instance's space with [`instance_ray`] and continues at the mesh's
    //! root; when the stack drops back below that point it restores the world ray. The direction
    //! is transformed, not renormalised, so a hit's `t` is a world distance in both levels and
    //! one closest hit serves both. Hits then carry their instance, and the surface is brought
    //! back to world space here ([`world_triangle`], [`normal_to_world`], [`vector_to_world`]).
    //!
    //! Layout: per instance, [`INSTANCE_TEXELS`] texels appended to `Scene::nodes` at
    //! `Scene::instance_first` (no new binding), in top-level leaf order: the rows of the
    //! world-to-instance transform (`[linear row, translation]` × 3), the rows of the
    //! instance-to-world transform (× 3), then `[root node of its mesh, handedness (the sign of
    //! the transform's determinant), 1 when the transform is the identity, 0]`. The scene's meshes
    //! used once and not moving are merged into one bottom level placed by the identity, which
    //! skips the transforms. Scenes without instances carry none of this.

    use glam::{Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::scene_data::{fetch_triangle, Scene, TriangleData};

    /// Texels per instance (see the module's layout).
    pub const INSTANCE_TEXELS: u32 = 7;

    /// An instance's texel `k` (0..INSTANCE_TEXELS).
    pub fn instance_texel(scene: &Scene, instance: u32, k: u32) -> Vec4 {
        scene.nodes.fetch(scene.instance_first + instance * INSTANCE_TEXELS + k)
    }

    /// `p` moved by the affine rows `r0`, `r1`, `r2` (`[linear row, translation]`).
    pub fn affine_point(r0: Vec4, r1: Vec4, r2: Vec4, p: Vec3) -> Vec3 {
        Vec3::new(r0.xyz().dot(p) + r0.w, r1.xyz().dot(p) + r1.w, r2.xyz().dot(p) + r2.w)
    }

    /// `v` moved by the linear part of the rows `r0`, `r1`, `r2`.
    pub fn affine_vector(r0: Vec4, r1: Vec4, r2: Vec4, v: Vec3) -> Vec3 {
        Vec3::new(r0.xyz().dot(v), r1.xyz().dot(v), r2.xyz().dot(v))
    }

    /// The world ray `origin + t * dir` in the space of `instance`, and the root node of its mesh.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct InstanceRay {
        pub origin: Vec3,
        pub dir: Vec3,
        pub root: u32,
    }

    /// The ray in `instance`'s space (unchanged for the identity) and its mesh's root node.
    #[inline(always)]
    pub fn instance_ray(scene: &Scene, instance: u32, origin: Vec3, dir: Vec3) -> InstanceRay {
        let info = instance_texel(scene, instance, 6);
        let root = info.x as u32;
        if info.z > 0.0 {
            InstanceRay { origin, dir, root }
        } else {
            let r0 = instance_texel(scene, instance, 0);
            let r1 = instance_texel(scene, instance, 1);
            let r2 = instance_texel(scene, instance, 2);
            InstanceRay { origin: affine_point(r0, r1, r2, origin), dir: affine_vector(r0, r1, r2, dir), root }
        }
    }

    /// The sign of `instance`'s determinant: -1 for a mirroring transform, whose world-space
    /// winding is reversed (the geometric normal is flipped back by it).
    pub fn instance_handedness(scene: &Scene, instance: u32) -> f32 {
        instance_texel(scene, instance, 6).y
    }

    /// Triangle `triangle` as `instance` places it, in world space. Without instances, the
    /// stored triangle.
    pub fn world_triangle(scene: &Scene, triangle: u32, instance: u32) -> TriangleData {
        let tri = fetch_triangle(scene, triangle);
        if scene.has_instances != 0 {
            let info = instance_texel(scene, instance, 6);
            if info.z > 0.0 {
                tri
            } else {
                let r0 = instance_texel(scene, instance, 3);
                let r1 = instance_texel(scene, instance, 4);
                let r2 = instance_texel(scene, instance, 5);
                TriangleData {
                    v0: affine_point(r0, r1, r2, tri.v0),
                    v1: affine_point(r0, r1, r2, tri.v1),
                    v2: affine_point(r0, r1, r2, tri.v2),
                    material: tri.material,
                    light: tri.light,
                    masked: tri.masked,
                }
            }
        } else {
            tri
        }
    }

    /// A normal of `instance`'s space in world space (not normalised): by the inverse transpose,
    /// whose columns are the world-to-instance rows. Without instances, `n`.
    pub fn normal_to_world(scene: &Scene, instance: u32, n: Vec3) -> Vec3 {
        if scene.has_instances != 0 {
            let r0 = instance_texel(scene, instance, 0);
            let r1 = instance_texel(scene, instance, 1);
            let r2 = instance_texel(scene, instance, 2);
            r0.xyz() * n.x + r1.xyz() * n.y + r2.xyz() * n.z
        } else {
            n
        }
    }

    /// A direction of `instance`'s space (a tangent) in world space. Without instances, `v`.
    pub fn vector_to_world(scene: &Scene, instance: u32, v: Vec3) -> Vec3 {
        if scene.has_instances != 0 {
            let r0 = instance_texel(scene, instance, 3);
            let r1 = instance_texel(scene, instance, 4);
            let r2 = instance_texel(scene, instance, 5);
            affine_vector(r0, r1, r2, v)
        } else {
            v
        }
    }
}
