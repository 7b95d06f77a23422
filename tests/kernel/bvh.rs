//! BVH: structural invariants, and closest hits equal to brute force on many random rays.

use crate::common;

use glam::{Vec2, Vec3};
use tracer::bvh::{self, BuildOptions, BuildQuality, Bvh, BvhError, WIDE};
use tracer::kernel::traverse::STACK_SIZE;
use tracer::scene::{self, Scene, Triangle};

/// xorshift32 with a float helper.
struct Rng(u32);

impl Rng {
    fn next(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        self.0
    }
    fn float(&mut self) -> f32 {
        (self.next() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.float()
    }
    fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0));
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// A scene of the vendored test data, `rel` relative to `tests/data/scenes/`.
fn test_scene(rel: &str) -> Scene {
    scene::load(&common::test_data(&format!("scenes/{rel}"))).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn tri(a: Vec3, b: Vec3, c: Vec3) -> Triangle {
    Triangle {
        positions: [a, b, c],
        normals: [Vec3::Z; 3],
        uvs: [Vec2::ZERO; 3],
        uvs1: Default::default(),
        tangents: Default::default(),
        material: 0,
    }
}

/// Random triangles of very different sizes, some axis-aligned, some degenerate, some
/// duplicated (exact ties in t).
fn triangle_soup(n: usize, seed: u32) -> Vec<Triangle> {
    let mut rng = Rng(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let c = Vec3::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0), rng.range(-10.0, 10.0));
        let size = 10f32.powf(rng.range(-2.0, 0.7));
        let mut t = tri(c + rng.unit_vector() * size, c + rng.unit_vector() * size, c + rng.unit_vector() * size);
        match rng.next() % 10 {
            0 => t.positions.iter_mut().for_each(|p| p.y = c.y), // axis-aligned (flat box)
            1 => t.positions[2] = t.positions[1],                // degenerate
            _ => {}
        }
        out.push(t);
        if rng.next().is_multiple_of(20) {
            out.push(t); // an exact duplicate
        }
    }
    out.truncate(n);
    out
}

fn leaf_sizes_within(bvh: &Bvh, max: u32) -> bool {
    bvh.nodes.iter().all(|n| n.count <= max)
}

/// Casts `rays` random rays (origins in and around the bounds, directions uniform plus some
/// axis-aligned ones) and requires the BVH's closest hit to equal brute force exactly.
/// Returns how many rays hit something.
fn compare_with_brute_force(name: &str, tris: &[Triangle], bvh: &Bvh, rays: usize, seed: u32) -> usize {
    let mut b = tracer::scene::Aabb::EMPTY;
    for t in tris {
        t.positions.iter().for_each(|p| b.extend(*p));
    }
    let (center, extent) = (b.center(), b.diagonal() * 0.6 + Vec3::splat(1e-3));
    let mut rng = Rng(seed);
    let mut hits = 0;
    let mut mismatches = Vec::new();
    for i in 0..rays {
        let origin = center + extent * Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        let mut dir = rng.unit_vector();
        match i % 16 {
            0 => dir = [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_X][(i / 16) % 4], // axis-aligned
            1 => dir.y = 0.0,                                                      // parallel to y slabs
            2 => dir *= 37.0,                                                      // not normalised
            _ => {}
        }
        let tmax = if i % 7 == 0 { rng.range(0.0, extent.length()) } else { f32::INFINITY };
        let expected = bvh::intersect_brute_force(tris, origin, dir, tmax);
        let got = bvh.intersect_closest(tris, origin, dir, tmax);
        if expected.is_some() {
            hits += 1;
        }
        if got != expected && mismatches.len() < 10 {
            mismatches
                .push(format!("ray {i}: origin {origin} dir {dir} tmax {tmax}: bvh {got:?}, brute force {expected:?}"));
        }
    }
    assert!(mismatches.is_empty(), "{name}: {mismatches:#?}");
    println!("{name}: {rays} rays, {hits} hits, {} nodes, depth {}", bvh.nodes.len(), bvh.depth());
    hits
}

/// The 4-wide hierarchy the kernel traverses: every binary leaf appears in exactly one wide
/// slot with its box, every wide node is referenced once, and the depth fits the stack.
fn check_wide(name: &str, bvh: &Bvh) -> (u32, u32) {
    let wide = bvh.widen().unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(wide.stack_needed <= STACK_SIZE as u32, "{name}: needs a stack of {}", wide.stack_needed);
    assert!(wide.stack_needed <= 3 * wide.depth, "{name}: at most three pending nodes per level");
    // Pushing leaves too: at most three more entries per level (and never fewer than nodes).
    let with_leaves = wide.stack_needed_with_leaves;
    assert!(
        wide.stack_needed <= with_leaves && with_leaves <= 3 * wide.depth + 1,
        "{name}: stack {} with leaves pushed, {} without, depth {}",
        with_leaves,
        wide.stack_needed,
        wide.depth
    );
    let mut leaves: Vec<(u32, u32, [u32; 6])> = Vec::new();
    let mut referenced = vec![0u32; wide.nodes.len()];
    referenced[0] = 1;
    for n in &wide.nodes {
        assert!((1..=WIDE as u32).contains(&n.children), "{name}: {} children", n.children);
        for c in 0..WIDE {
            if c >= n.children as usize {
                assert!(n.min[c].cmpgt(n.max[c]).all(), "{name}: unused slot {c} must be an empty box");
                continue;
            }
            if n.count[c] == 0 {
                referenced[n.first[c] as usize] += 1;
            } else {
                let (lo, hi) = (n.min[c], n.max[c]);
                let bits = [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z].map(f32::to_bits);
                leaves.push((n.first[c], n.count[c], bits));
            }
        }
    }
    assert!(referenced.iter().all(|&r| r == 1), "{name}: every wide node is referenced once");
    let mut expected: Vec<(u32, u32, [u32; 6])> = bvh
        .nodes
        .iter()
        .filter(|n| n.is_leaf())
        .map(|n| (n.first, n.count, [n.min.x, n.min.y, n.min.z, n.max.x, n.max.y, n.max.z].map(f32::to_bits)))
        .collect();
    leaves.sort();
    expected.sort();
    assert_eq!(leaves, expected, "{name}: the wide hierarchy keeps every leaf, with its box");
    (wide.depth, wide.stack_needed)
}

fn check(name: &str, tris: &[Triangle], rays: usize) {
    let bvh = bvh::build(tris).unwrap();
    bvh.validate(tris).unwrap_or_else(|e| panic!("{name}: {e}"));
    let (wide_depth, stack) = check_wide(name, &bvh);
    println!("{name}: binary depth {}, 4-wide depth {wide_depth}, stack needed {stack}", bvh.depth());
    assert!(leaf_sizes_within(&bvh, BuildOptions::default().max_leaf_size));
    let hits = compare_with_brute_force(name, tris, &bvh, rays, 0x9E37_79B9);
    assert!(hits > rays / 10, "{name}: only {hits} of {rays} rays hit: the comparison proves little");
}

#[test]
fn cornell_box_matches_brute_force() {
    check("cornell box", &scene::cornell_box().triangles, 20_000);
    // The OBJ repeats two faces of each box: exact ties, settled by triangle index.
    check("cornell box (OBJ)", &test_scene("cornell-box/CornellBox-Original.obj").triangles, 10_000);
}

#[test]
fn duck_matches_brute_force() {
    check("duck", &test_scene("khronos/Duck/glTF-Binary/Duck.glb").triangles, 10_000);
}

#[test]
fn triangle_soup_matches_brute_force() {
    check("soup", &triangle_soup(5000, 7), 10_000);
}

/// Scale: the generated benchmark scene, 1,232,000 triangles (a terrain heightfield and 500
/// overlapping spheres), on a few rays (brute force visits every triangle for each). This ran
/// on LittlestTokyo (141,802 triangles, 600 rays), which is not in the repository; the generated
/// scene is larger and as deep, and needs no file.
#[test]
fn a_large_generated_scene_matches_brute_force_on_a_few_rays() {
    let s = scene::terrain_and_spheres();
    check("terrain and spheres", &s.triangles, 120);
}

#[test]
fn every_preset_and_leaf_size_is_valid() {
    let tris = triangle_soup(3000, 11);
    for quality in [BuildQuality::Fastest, BuildQuality::Fast, BuildQuality::Medium, BuildQuality::Slow] {
        for max_leaf_size in [1, 2, 4, 8] {
            let options = BuildOptions { quality, max_leaf_size, ..BuildOptions::default() };
            let bvh = bvh::build_with(&tris, &options).unwrap();
            bvh.validate(&tris).unwrap_or_else(|e| panic!("{options:?}: {e}"));
            assert!(leaf_sizes_within(&bvh, max_leaf_size), "{options:?}");
            compare_with_brute_force(&format!("{options:?}"), &tris, &bvh, 1000, 3);
        }
    }
}

#[test]
fn edge_cases() {
    assert_eq!(bvh::build(&[]), Err(BvhError::Empty));

    let one = [tri(Vec3::ZERO, Vec3::X, Vec3::Y)];
    let b = bvh::build(&one).unwrap();
    assert_eq!(b.nodes.len(), 1);
    assert_eq!((b.nodes[0].first, b.nodes[0].count), (0, 1));
    assert_eq!(b.triangle_order, vec![0]);
    b.validate(&one).unwrap();
    let hit = b.intersect_closest(&one, Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
    assert_eq!((hit.triangle, hit.t, hit.u, hit.v), (0, 1.0, 0.25, 0.25));
    assert!(b.intersect_closest(&one, Vec3::new(0.25, 0.25, 1.0), Vec3::Z, f32::INFINITY).is_none());
    assert!(b.intersect_closest(&one, Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, 0.5).is_none());

    let mut nan = one;
    nan[0].positions[1].x = f32::NAN;
    assert_eq!(bvh::build(&nan), Err(BvhError::NonFinite(0)));

    // Everything in one point: a zero-size scene box must not break Morton coding.
    let point = vec![tri(Vec3::ONE, Vec3::ONE, Vec3::ONE); 100];
    let b = bvh::build(&point).unwrap();
    b.validate(&point).unwrap();
    check_wide("point", &b);
    // A single leaf: the wide root has one child.
    let wide = bvh::build(&one).unwrap().widen().unwrap();
    assert_eq!(
        (wide.nodes.len(), wide.depth, wide.stack_needed, wide.stack_needed_with_leaves, wide.nodes[0].children),
        (1, 1, 0, 1, 1)
    );
    // Deep binary trees: triangles at exponentially growing distances along a line.
    let line: Vec<Triangle> = (0..2000)
        .map(|i| 1.01f32.powi(i))
        .map(|x| tri(Vec3::new(x, 0.0, 0.0), Vec3::new(x, 1.0, 0.0), Vec3::new(x, 0.0, 1.0)))
        .collect();
    let b = bvh::build(&line).unwrap();
    println!("line: binary depth {}, 4-wide depth and stack {:?}", b.depth(), check_wide("line", &b));
    // Many identical triangles: once a chain thousands of levels deep (and a quadratic build),
    // now one builder primitive split into a balanced subtree (`bvh::coincident`).
    let many = vec![tri(Vec3::ZERO, Vec3::X, Vec3::Y); 5_000];
    let b = bvh::build(&many).unwrap();
    let (depth, stack) = check_wide("identical", &b);
    assert!(depth <= 14 && stack <= 3 * depth, "identical: depth {depth} (binary: 13 levels), stack {stack}");
    assert!(b.widen().unwrap().stack_needed_with_leaves <= STACK_SIZE as u32);
    // Nested triangles (each 1% larger than the last, about one point) still build a chain:
    // leaves are intersected at once, so it needs almost no stack however deep it is, but
    // pushing its leaves would need far more than the kernel's stack (what `tracer::pack`'s
    // leaf_stack_limit is for).
    let nested: Vec<Triangle> = (0..5_000)
        .map(|i| 1.01f32.powi(i))
        .map(|s| tri(Vec3::new(-s, -s, 0.0), Vec3::new(s, -s, 0.0), Vec3::new(0.0, s, 0.0)))
        .collect();
    let b = bvh::build(&nested).unwrap();
    let (depth, stack) = check_wide("nested", &b);
    assert!(depth > 100 && stack <= 2, "nested: depth {depth}, stack {stack}");
    assert!(b.widen().unwrap().stack_needed_with_leaves > STACK_SIZE as u32);

    // Many identical triangles: all tie; the smallest index wins.
    let same = vec![tri(Vec3::ZERO, Vec3::X, Vec3::Y); 50];
    let b = bvh::build(&same).unwrap();
    b.validate(&same).unwrap();
    let hit = b.intersect_closest(&same, Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
    assert_eq!(hit.triangle, 0);
}

#[test]
fn validate_catches_broken_hierarchies() {
    let tris = triangle_soup(500, 5);
    let good = bvh::build(&tris).unwrap();
    good.validate(&tris).unwrap();
    assert!(good.sah_cost() > 1.0 && good.depth() > 3 && good.leaf_count() > 1);

    let interior = good.nodes.iter().position(|n| !n.is_leaf()).unwrap();
    let leaf = good.nodes.iter().position(|n| n.is_leaf()).unwrap();

    let mut shrunk = good.clone();
    let child = shrunk.nodes[interior].first as usize;
    shrunk.nodes[child].max += Vec3::splat(1.0);
    assert!(shrunk.validate(&tris).is_err(), "child box outside its parent");

    let mut tight = good.clone();
    tight.nodes[leaf].min = tight.nodes[leaf].max;
    assert!(tight.validate(&tris).is_err(), "leaf box not containing its triangles");

    let mut twice = good.clone();
    twice.triangle_order[1] = twice.triangle_order[0];
    assert!(twice.validate(&tris).is_err(), "triangle referenced twice");

    let mut cycle = good.clone();
    let c = cycle.nodes[0].first as usize;
    cycle.nodes[c].first = 0;
    cycle.nodes[c].count = 0;
    assert!(cycle.validate(&tris).is_err(), "child pointing back at the root");
    let _ = cycle.depth(); // terminates on a cyclic graph
    assert!(cycle.widen().is_err(), "widening refuses a cyclic graph instead of looping");
    let _ = cycle.intersect_closest(&tris, Vec3::ZERO, Vec3::X, 1.0); // and traversal returns
}

#[test]
fn better_presets_have_lower_sah_cost() {
    let s = test_scene("khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let cost = |quality| {
        bvh::build_with(&s.triangles, &BuildOptions { quality, ..BuildOptions::default() }).unwrap().sah_cost()
    };
    let (fastest, fast, medium) = (cost(BuildQuality::Fastest), cost(BuildQuality::Fast), cost(BuildQuality::Medium));
    println!("SAH cost: fastest {fastest:.1}, fast {fast:.1}, medium {medium:.1}");
    assert!(medium <= fastest * 1.02, "medium {medium} vs fastest {fastest}");
}

/// `Bvh::refit` (a deformed mesh's bottom level at a pose, `pack::posing`): over triangles
/// moved (a soup twisted about Y by an angle growing with height, then stretched), the
/// refitted hierarchy holds every structural invariant against the moved triangles and finds
/// the brute-force closest hit on every ray; refitted to the triangles it was built over it is
/// the built one exactly; and its SAH cost against a hierarchy built for the moved triangles
/// grows with the deformation (what `REFIT_BOUND` bounds). A wrong count, or a corrupt
/// hierarchy, is an error.
#[test]
fn a_refitted_bvh_over_moved_triangles_matches_brute_force() {
    let rest = triangle_soup(4000, 11);
    let built = bvh::build(&rest).unwrap();
    let mut same = built.clone();
    same.refit(&rest).unwrap();
    assert_eq!(same, built, "refitted in place, nothing moves");
    let twist = |tris: &[Triangle], amount: f32| -> Vec<Triangle> {
        let moved = |p: Vec3| {
            let (s, c) = (p.y * amount).sin_cos();
            Vec3::new(p.x * c - p.z * s, p.y * (1.0 + amount), p.x * s + p.z * c)
        };
        tris.iter().map(|t| Triangle { positions: t.positions.map(moved), ..*t }).collect()
    };
    let mut costs = Vec::new();
    for amount in [0.0, 0.05, 0.2, 0.5] {
        let moved = twist(&rest, amount);
        let mut refitted = built.clone();
        refitted.refit(&moved).unwrap();
        refitted.validate(&moved).unwrap_or_else(|e| panic!("twisted by {amount}: {e}"));
        compare_with_brute_force(&format!("refitted, twist {amount}"), &moved, &refitted, 3000, 0x51);
        let rebuilt = bvh::build(&moved).unwrap().sah_cost();
        println!("twist {amount}: SAH refitted {:.1}, rebuilt {rebuilt:.1}", refitted.sah_cost());
        costs.push(refitted.sah_cost() / rebuilt);
    }
    // Against a hierarchy built for the moved triangles (measured: 1.00, 1.05, 1.28, 1.51).
    assert!(costs[0] == 1.0 && costs.windows(2).all(|w| w[1] > w[0]), "refitted / rebuilt SAH: {costs:?}");
    assert!(built.clone().refit(&rest[1..]).is_err(), "one triangle short");
    // A corrupt hierarchy is an error, not a panic: a child index past the nodes, a leaf past
    // the triangle order, a child before its parent.
    for (node, first) in [(0, u32::MAX - 1), (built.nodes.len() - 1, u32::MAX - 1), (1, 0)] {
        let mut bad = built.clone();
        bad.nodes[node].first = first;
        assert!(bad.refit(&rest).is_err(), "node {node} naming {first}");
    }
}
