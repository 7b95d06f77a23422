//! Triangles with identical bounding boxes, built over as one primitive.
//!
//! obvhs' PLOC pairs each cluster with the neighbour whose merged box is smallest and merges
//! only mutual pairs. Among identical boxes every merged area ties, each cluster picks the same
//! side, pairs are rarely mutual and one pass merges almost nothing: n identical boxes take
//! about n passes, a quadratic build (a 636-byte glTF of 21,845 triangles at one point spent
//! 5.6 s building; 1,000,000 did not finish). Building over one primitive per large set of
//! identical boxes and expanding each back into its triangles afterwards (`super::convert`, a
//! balanced subtree) keeps the build O(n log n) whatever the positions.

use std::collections::HashMap;

use obvhs::aabb::Aabb;

/// Triangles sharing one box with more than this many others are built over as one primitive.
/// Smaller sets (the two halves of an axis-aligned quad share a box) cost PLOC a few passes
/// and keep today's hierarchy; n triangles in groups of at most this size cost O(n x this).
pub(super) const LARGE_GROUP: usize = 32;

/// The builder's primitives, each one triangle or a large group of coincident ones, and the
/// triangles each stands for, in ascending triangle order.
pub(super) struct Coincident {
    /// One box per primitive: what the builder sees.
    pub boxes: Vec<Aabb>,
    /// `members[start[p] .. start[p + 1]]` are primitive `p`'s triangles.
    start: Vec<u32>,
    members: Vec<u32>,
}

impl Coincident {
    /// Groups triangles whose boxes are bit-identical, or `None` when no box is shared by more
    /// than [`LARGE_GROUP`] triangles (the common case: the build then runs on the triangles as
    /// they are, and the hierarchy is the one it always was).
    pub fn find(aabbs: &[Aabb]) -> Option<Coincident> {
        let key = |b: &Aabb| {
            let (min, max) = (b.min.to_array(), b.max.to_array());
            [min[0], min[1], min[2], max[0], max[1], max[2]].map(|v| if v == 0.0 { 0 } else { v.to_bits() })
        };
        let mut group_of: HashMap<[u32; 6], u32> = HashMap::with_capacity(aabbs.len());
        let mut group = Vec::with_capacity(aabbs.len());
        let mut sizes: Vec<u32> = Vec::new();
        for b in aabbs {
            let next = sizes.len() as u32;
            let g = *group_of.entry(key(b)).or_insert(next);
            if g == next {
                sizes.push(0);
            }
            sizes[g as usize] += 1;
            group.push(g);
        }
        if sizes.iter().all(|&n| n as usize <= LARGE_GROUP) {
            return None;
        }
        // Primitives in order of first appearance: a large group is one, its first triangle
        // placing it; every other triangle is its own.
        let mut primitive_of_group = vec![u32::MAX; sizes.len()];
        let mut primitive = Vec::with_capacity(aabbs.len());
        let mut boxes = Vec::new();
        for (t, &g) in group.iter().enumerate() {
            let large = sizes[g as usize] as usize > LARGE_GROUP;
            let p = if large && primitive_of_group[g as usize] != u32::MAX {
                primitive_of_group[g as usize]
            } else {
                boxes.push(aabbs[t]);
                let p = boxes.len() as u32 - 1;
                if large {
                    primitive_of_group[g as usize] = p;
                }
                p
            };
            primitive.push(p);
        }
        // Counting sort of the triangles by primitive, stable so members stay in ascending order.
        let mut start = vec![0u32; boxes.len() + 1];
        for &p in &primitive {
            start[p as usize + 1] += 1;
        }
        for p in 0..boxes.len() {
            start[p + 1] += start[p];
        }
        let mut fill = start.clone();
        let mut members = vec![0u32; aabbs.len()];
        for (t, &p) in primitive.iter().enumerate() {
            members[fill[p as usize] as usize] = t as u32;
            fill[p as usize] += 1;
        }
        Some(Coincident { boxes, start, members })
    }

    /// The triangles of primitive `p` (empty for an index out of range).
    pub fn members(&self, p: u32) -> &[u32] {
        let p = p as usize;
        match (self.start.get(p), self.start.get(p + 1)) {
            (Some(&a), Some(&b)) => self.members.get(a as usize..b as usize).unwrap_or(&[]),
            _ => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use glam::{Vec2, Vec3};

    use crate::bvh::{build, intersect_brute_force, BuildOptions, Bvh};
    use crate::scene::Triangle;

    fn tri(positions: [Vec3; 3]) -> Triangle {
        Triangle {
            positions,
            normals: [Vec3::Z; 3],
            uvs: [Vec2::ZERO; 3],
            uvs1: Default::default(),
            tangents: Default::default(),
            material: 0,
        }
    }

    /// xorshift32 in [0, 1): deterministic scenes without a dependency.
    fn random(state: &mut u32) -> f32 {
        *state ^= *state << 13;
        *state ^= *state >> 17;
        *state ^= *state << 5;
        (*state >> 8) as f32 / (1u32 << 24) as f32
    }

    fn random_triangles(n: usize, seed: u32, size: f32) -> Vec<Triangle> {
        let mut s = seed;
        let v = |s: &mut u32| Vec3::new(random(s), random(s), random(s));
        (0..n)
            .map(|_| {
                let c = v(&mut s) * 10.0;
                tri([c, c + (v(&mut s) - 0.5) * size, c + (v(&mut s) - 0.5) * size])
            })
            .collect()
    }

    /// Every ray of a fan through the scene hits what brute force hits (ties to the smaller
    /// triangle index, which coincident triangles always tie on).
    fn assert_traversal_agrees(bvh: &Bvh, triangles: &[Triangle]) {
        bvh.validate(triangles).expect("a valid BVH");
        let max_leaf = BuildOptions::default().max_leaf_size;
        assert!(bvh.nodes.iter().all(|n| n.count <= max_leaf), "leaves hold at most {max_leaf} triangles");
        let mut s = 7;
        for _ in 0..200 {
            let origin = Vec3::new(random(&mut s), random(&mut s), -5.0) * Vec3::new(10.0, 10.0, 1.0);
            let dir = Vec3::new(random(&mut s) - 0.5, random(&mut s) - 0.5, 1.0);
            let got = bvh.intersect_closest(triangles, origin, dir, f32::MAX);
            let want = intersect_brute_force(triangles, origin, dir, f32::MAX);
            assert_eq!(got, want, "ray from {origin} along {dir}");
        }
    }

    #[test]
    fn distinct_and_few_shared_boxes_build_as_before() {
        // Distinct boxes, and boxes shared by up to LARGE_GROUP triangles (a quad's halves).
        let mut triangles = random_triangles(1000, 1, 1.0);
        for (i, t) in random_triangles(40, 2, 1.0).into_iter().enumerate() {
            triangles.extend(std::iter::repeat_n(t, 1 + i % super::LARGE_GROUP));
        }
        let aabbs: Vec<_> = triangles.iter().map(super::super::triangle_aabb).collect();
        assert!(super::Coincident::find(&aabbs).is_none(), "no group: the triangles go to the builder as they are");
        assert_traversal_agrees(&build(&triangles).expect("BVH"), &triangles);
    }

    /// Identical triangles, and groups of them among distinct ones: a balanced subtree per
    /// group (its depth logarithmic), every triangle referenced once, traversal exact.
    #[test]
    fn coincident_triangles_make_a_balanced_valid_tree() {
        let one = tri([Vec3::new(1.0, 1.0, 0.0), Vec3::new(9.0, 1.0, 0.0), Vec3::new(1.0, 9.0, 0.0)]);
        let identical = vec![one; 20_000];
        let bvh = build(&identical).expect("BVH");
        assert_traversal_agrees(&bvh, &identical);
        assert!(bvh.depth() <= 16, "20,000 in leaves of 4: depth {} (balanced: 13)", bvh.depth());

        let mut mixed = random_triangles(3000, 3, 1.0);
        for (i, t) in random_triangles(30, 5, 2.0).into_iter().enumerate() {
            mixed.extend(std::iter::repeat_n(t, 1 + i * 37));
        }
        mixed.extend(random_triangles(3000, 9, 1.0));
        assert_traversal_agrees(&build(&mixed).expect("BVH"), &mixed);
    }

    /// The bound issue 31 sets: identical and clustered triangles build within twice the time
    /// of as many random ones (before, identical ones were quadratic: 21,845 took 5.6 s and a
    /// million did not finish). Medians of alternated runs, so a busy machine slows all alike;
    /// what this catches is a build that grows faster than the random one, not a slow machine.
    #[test]
    fn coincident_and_clustered_triangles_build_as_fast_as_random_ones() {
        let n = 1_000_000;
        let random = random_triangles(n, 11, 0.05);
        let one = tri([Vec3::ZERO, Vec3::X, Vec3::Y]);
        let identical = vec![one; n];
        // Distinct triangles whose centroids all lie within a micrometre.
        let clustered = random_triangles(n, 13, 1.0)
            .into_iter()
            .map(|t| tri(t.positions.map(|p| (p - t.positions[0]) * 1e-6 + Vec3::splat(1.0))))
            .collect::<Vec<_>>();
        let time = |triangles: &[Triangle]| {
            let start = Instant::now();
            let bvh = build(triangles).expect("BVH");
            assert_eq!(bvh.triangle_order.len(), triangles.len());
            start.elapsed().as_secs_f64()
        };
        let mut samples: [Vec<f64>; 3] = Default::default();
        for _ in 0..3 {
            for (s, triangles) in samples.iter_mut().zip([&random, &identical, &clustered]) {
                s.push(time(triangles));
            }
        }
        let median = |s: &mut Vec<f64>| {
            s.sort_by(f64::total_cmp);
            s[s.len() / 2]
        };
        let [r, i, c] = samples.each_mut().map(median);
        eprintln!("build of {n} triangles: random {r:.3} s, identical {i:.3} s, clustered {c:.3} s");
        assert!(i <= 2.0 * r, "identical triangles: {i:.3} s against {r:.3} s for random ones");
        assert!(c <= 2.0 * r, "clustered triangles: {c:.3} s against {r:.3} s for random ones");
    }
}
