// Every construct the kernel subset supports, in one module: it must compile, run on the CPU
// and expose its IR.

#[kernel_dsl::kernel]
pub mod k {
    use glam::{UVec4, Vec3, Vec4};
    use kernel_dsl::Texels;

    pub const KIND_DIFFUSE: u32 = 0;
    pub const KIND_MIRROR: u32 = 1;
    pub const STACK: usize = 32;
    pub const SCALE: f32 = 1.0 / 16777216.0;

    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Ray {
        pub origin: Vec3,
        pub dir: Vec3,
    }

    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Hit {
        pub ray: Ray,
        pub t: f32,
        pub kind: u32,
    }

    #[resources]
    pub struct Scene {
        pub vertices: kernel_dsl::Texels<glam::Vec4>,
        pub indices: Texels<UVec4>,
        pub vertex_count: u32,
        pub exposure: f32,
    }

    /// Structs, nested structs, struct literals, field access, glam methods.
    pub fn advance(ray: Ray, t: f32) -> Hit {
        let p = ray.origin + ray.dir.normalize() * t;
        Hit { ray: Ray { origin: p, dir: ray.dir }, t: p.length().max(0.0), kind: KIND_DIFFUSE }
    }

    /// Arrays with indexing, let/let mut with and without annotations, while, casts.
    pub fn stack_sum(n: u32) -> u32 {
        let mut stack: [u32; 32] = [0; STACK];
        let mut top = 0;
        while top < n && top < 32 {
            stack[top as usize] = top * 3;
            top += 1;
        }
        let mut total: u32 = 0;
        for i in 0..top {
            total = total.wrapping_add(stack[i as usize]);
        }
        total
    }

    /// if/else as an expression, loop with break and continue, early return.
    pub fn first_odd_square_over(limit: u32) -> u32 {
        if limit == 0 {
            return 1;
        }
        let mut i = 0u32;
        loop {
            i += 1;
            if i % 2 == 0 {
                continue;
            }
            if i * i > limit {
                break;
            }
        }
        let found = i * i;
        let doubled = if found > 100 { found } else { found * 2 };
        doubled
    }

    /// Inclusive ranges, &mut parameters, wrapping ops, shifts by literals, casts.
    pub fn hash_steps(state: &mut u32, steps: u32) -> f32 {
        for _i in 1..=steps {
            *state ^= *state << 13;
            *state ^= *state >> 17;
            *state ^= *state << 5;
            *state = state.wrapping_mul(747796405).wrapping_add(2891336453);
        }
        (*state >> 8) as f32 * SCALE
    }

    /// match on integers: literals, consts, alternatives, negative literals and `_`.
    pub fn kind_weight(kind: u32, sign: i32) -> f32 {
        let w = match kind {
            KIND_DIFFUSE => 0.5,
            KIND_MIRROR | 7 => 1.0,
            _ => 0.0,
        };
        let s = match sign {
            -1 => -1.0,
            0 => 0.0,
            5 | _ => 1.0,
        };
        w * s
    }

    /// The resources struct through a shared reference: texel fetches and uniforms.
    pub fn fetch_vertex(scene: &Scene, index: u32) -> Vec4 {
        let i = scene.indices.fetch(index);
        if i.x < scene.vertex_count {
            scene.vertices.fetch(i.x) * scene.exposure
        } else {
            Vec4::ZERO
        }
    }

    /// Integer/float conversions and f32 builtins.
    pub fn misc(x: f32, n: i32) -> f32 {
        let bits = x.to_bits();
        let back = f32::from_bits(bits);
        let m = (n.wrapping_neg() as f32).abs();
        let v = Vec3::splat(back).dot(Vec3::new(1.0, 0.0, 0.0));
        (v + m).sqrt().clamp(0.0, 100.0) + core::f32::consts::PI * 0.0
    }
}

fn main() {
    use glam::{UVec4, Vec3, Vec4};

    let hit = k::advance(k::Ray { origin: Vec3::ZERO, dir: Vec3::new(0.0, 0.0, 2.0) }, 3.0);
    assert_eq!(hit.ray.origin, Vec3::new(0.0, 0.0, 3.0));
    assert_eq!(hit.t, 3.0);
    assert_eq!(k::stack_sum(4), 3 * (1 + 2 + 3));
    assert_eq!(k::first_odd_square_over(10), 50);
    assert_eq!(k::first_odd_square_over(0), 1);
    let mut state = 1;
    let f = k::hash_steps(&mut state, 3);
    assert!((0.0..1.0).contains(&f));
    assert_eq!(k::kind_weight(k::KIND_MIRROR, -1), -1.0);
    assert_eq!(k::kind_weight(k::KIND_DIFFUSE, 5), 0.5);
    assert_eq!(k::kind_weight(3, 5), 0.0);
    let scene = k::Scene {
        vertices: vec![Vec4::ONE, Vec4::splat(2.0)].into(),
        indices: vec![UVec4::new(1, 0, 0, 0)].into(),
        vertex_count: 2,
        exposure: 0.5,
    };
    assert_eq!(k::fetch_vertex(&scene, 0), Vec4::ONE);
    assert_eq!(k::misc(4.0, 5), 3.0);

    let ir = k::kernel_ir();
    assert_eq!(ir.name, "k");
    let names: Vec<&str> = ir.items.iter().map(|i| i.name()).collect();
    for expected in
        ["KIND_DIFFUSE", "Ray", "Hit", "Scene", "advance", "stack_sum", "kind_weight", "fetch_vertex", "misc"]
    {
        assert!(names.contains(&expected), "{expected} missing from the IR: {names:?}");
    }
    let scene_def = ir.items.iter().find_map(|i| match i {
        kernel_dsl::ir::Item::Struct(s) if s.name == "Scene" => Some(s),
        _ => None,
    });
    assert!(scene_def.is_some_and(|s| s.resources && s.fields.len() == 4));

    // `#[resources]` also implements `kernel_dsl::Resources`: the fields by name, in order, to walk and to fill.
    use kernel_dsl::{Resource, ResourceMut, Resources};
    let mut scene = scene;
    let fields: Vec<(&str, &str)> = scene.fields().iter().map(|(n, r)| (*n, r.dsl_type())).collect();
    assert_eq!(
        fields,
        [("vertices", "Texels<Vec4>"), ("indices", "Texels<UVec4>"), ("vertex_count", "u32"), ("exposure", "f32")]
    );
    assert!(matches!(scene.fields()[0].1, Resource::Vec4s(t) if t.len() == 2));
    for (_, field) in scene.fields_mut() {
        if let ResourceMut::U32(n) = field {
            *n = 7;
        }
    }
    assert_eq!(scene.vertex_count, 7);

    // `match` patterns: consts by name, alternatives, negative literals, and `_` (also
    // inside an alternative) as an arm without patterns.
    use kernel_dsl::ir::{ExprKind, Item, Stmt, UnOp};
    let kind_weight = ir.items.iter().find_map(|i| match i {
        Item::Fn(f) if f.name == "kind_weight" => Some(f),
        _ => None,
    });
    let stmts = &kind_weight.expect("kind_weight in the IR").body.stmts;
    let arms = |i: usize| match &stmts[i] {
        Stmt::Let { init: Some(init), .. } => match &init.kind {
            ExprKind::Match { arms, .. } => arms.clone(),
            other => panic!("not a match: {other:?}"),
        },
        other => panic!("not a let: {other:?}"),
    };
    let kinds = arms(0);
    assert_eq!(kinds.iter().map(|a| a.patterns.len()).collect::<Vec<_>>(), [1, 2, 0]);
    assert_eq!(kinds[0].patterns[0].kind, ExprKind::Path(vec!["KIND_DIFFUSE".to_string()]));
    assert_eq!(kinds[1].patterns[0].kind, ExprKind::Path(vec!["KIND_MIRROR".to_string()]));
    let signs = arms(1);
    assert_eq!(signs.iter().map(|a| a.patterns.len()).collect::<Vec<_>>(), [1, 1, 0]);
    assert!(matches!(&signs[0].patterns[0].kind, ExprKind::Unary { op: UnOp::Neg, .. }));
}
