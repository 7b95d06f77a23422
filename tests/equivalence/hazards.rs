//! Divergence hazards: the DSL's rule (Rust's meaning) on every target, checked on functions
//! of a kernel module of their own (`kernel`), linked into every runtime's program.

use super::*;

/// Rust, GLSL ES 3.00 and WGSL differ on these operations (DESIGN.md principle 2, the table in
/// docs/dsl.md); the path-tracing kernel does not exercise all of them directly.
#[kernel_dsl::kernel]
pub mod kernel {
    use glam::{IVec2, UVec2, UVec4, Vec2, Vec4};

    pub fn float_to_u32(x: f32) -> u32 {
        x as u32
    }

    pub fn float_to_i32(x: f32) -> i32 {
        x as i32
    }

    pub fn u32_to_float(x: u32) -> f32 {
        x as f32
    }

    /// At most 24 significant bits: codegen may use a plain conversion here.
    pub fn u24_to_float(x: u32) -> f32 {
        (x >> 8) as f32
    }

    pub fn i32_to_float(x: i32) -> f32 {
        x as f32
    }

    pub fn div_rem_i32(a: i32, b: i32) -> IVec2 {
        IVec2::new(a / b, a % b)
    }

    pub fn div_rem_u32(a: u32, b: u32) -> UVec2 {
        UVec2::new(a / b, a % b)
    }

    /// Shift amounts are masked to 0..31 (`wrapping_shl/shr`); `>>` on i32 is arithmetic.
    pub fn shifts(x: u32, n: u32) -> UVec4 {
        let s = x as i32;
        UVec4::new(x.wrapping_shl(n), x.wrapping_shr(n), s.wrapping_shl(n) as u32, s.wrapping_shr(n) as u32)
    }

    /// Shifts by literals, the only form plain `<<`/`>>` take.
    pub fn literal_shifts(x: u32) -> UVec4 {
        let s = x as i32;
        UVec4::new(x << 31, x >> 31, (s >> 31) as u32, (s >> 1) as u32)
    }

    pub fn wrapping_ops(a: u32, b: u32) -> UVec4 {
        let s = a as i32;
        UVec4::new(a.wrapping_add(b), a.wrapping_sub(b), a.wrapping_mul(b), s.wrapping_neg() as u32)
    }

    pub fn fmod(a: f32, b: f32) -> f32 {
        a % b
    }

    pub fn rounding(x: f32) -> Vec4 {
        Vec4::new(x.round(), x.fract(), x.signum(), x.trunc())
    }

    pub fn floor_ceil_abs(x: f32) -> Vec4 {
        Vec4::new(x.floor(), x.ceil(), x.abs(), -x)
    }

    /// bit 0: NaN, bit 1: finite, bit 2: infinite.
    pub fn classify(x: f32) -> u32 {
        let mut c = 0;
        if x.is_nan() {
            c |= 1;
        }
        if x.is_finite() {
            c |= 2;
        }
        if x.is_infinite() {
            c |= 4;
        }
        c
    }

    /// The IEEE specials the DSL's literals stand for, and arithmetic producing them.
    pub fn specials(x: f32) -> Vec4 {
        Vec4::new(f32::NAN, f32::INFINITY, f32::NEG_INFINITY, x * f32::INFINITY)
    }

    pub fn min_max(a: f32, b: f32) -> Vec2 {
        Vec2::new(a.min(b), a.max(b))
    }

    pub fn to_bits(x: f32) -> u32 {
        x.to_bits()
    }
}

// ---------------------------------------------------------------------------------------------
// Divergence hazards: the DSL's rule (Rust's meaning) on every target.

#[test]
fn float_to_int_conversions_saturate_like_rust() {
    let mut eq = equivalence();
    let xs: Vec<(f32,)> = floats_with_specials(1 << 16, 11, any_float).into_iter().map(|x| (x,)).collect();
    assert_equivalent(&mut eq, "float_to_u32", &xs, |_, &(x,)| (kernel::float_to_u32(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "float_to_i32", &xs, |_, &(x,)| (kernel::float_to_i32(x),), Tolerance::EXACT);
}

#[test]
fn int_to_float_rounds_to_nearest_even() {
    let mut eq = equivalence();
    let mut r = TestRng::new(12);
    let mut xs: Vec<u32> = vec![0, 1, u32::MAX, u32::MAX - 127, u32::MAX - 128, 0x8000_0000, 0x7fff_ffff];
    for k in 23..32 {
        let base = 1u32 << k;
        for d in 0..=64 {
            xs.push(base.wrapping_add(d));
            xs.push(base.wrapping_sub(d));
            // Exact halfway points between neighbouring floats (ties go to even).
            let step = 1u32 << (k - 23).max(0);
            xs.push(base.wrapping_add(step * d).wrapping_add(step / 2));
        }
    }
    while xs.len() < 1 << 17 {
        xs.push(r.next_u32() >> (r.next_u32() % 32));
    }
    let u: Vec<(u32,)> = xs.iter().map(|&x| (x,)).collect();
    assert_equivalent(&mut eq, "u32_to_float", &u, |_, &(x,)| (kernel::u32_to_float(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "u24_to_float", &u, |_, &(x,)| (kernel::u24_to_float(x),), Tolerance::EXACT);
    let i: Vec<(i32,)> = xs.iter().flat_map(|&x| [(x as i32,), ((x as i32).wrapping_neg(),)]).collect();
    assert_equivalent(&mut eq, "i32_to_float", &i, |_, &(x,)| (kernel::i32_to_float(x),), Tolerance::EXACT);
}

#[test]
fn integer_division_truncates_toward_zero() {
    let mut eq = equivalence();
    let mut r = TestRng::new(13);
    let mut pairs: Vec<(i32, i32)> = Vec::new();
    for a in [-7, 7, -1, 1, 0, 6, -6, i32::MIN, i32::MAX, i32::MIN + 1] {
        for b in [-7, 7, -2, 2, -1, 1, 3, -3, i32::MIN, i32::MAX] {
            pairs.push((a, b));
        }
    }
    while pairs.len() < 1 << 16 {
        let a = r.next_u32() as i32 >> (r.next_u32() % 32);
        let b = r.next_u32() as i32 >> (r.next_u32() % 32);
        if b != 0 {
            pairs.push((a, b));
        }
    }
    // i32::MIN / -1 overflows: Rust panics (a kernel must not do it); GLSL's lp_div_i32 and WGSL
    // both give the wrapping result (MIN, remainder 0), which is what this reference states.
    assert_equivalent(
        &mut eq,
        "div_rem_i32",
        &pairs,
        |_, &(a, b)| {
            if (a, b) == (i32::MIN, -1) {
                (IVec2::new(a.wrapping_div(b), a.wrapping_rem(b)),)
            } else {
                (kernel::div_rem_i32(a, b),)
            }
        },
        Tolerance::EXACT,
    );
    let unsigned: Vec<(u32, u32)> = pairs.iter().map(|&(a, b)| (a as u32, b as u32)).collect();
    assert_equivalent(&mut eq, "div_rem_u32", &unsigned, |_, &(a, b)| (kernel::div_rem_u32(a, b),), Tolerance::EXACT);
}

#[test]
fn shifts_and_wrapping_arithmetic() {
    let mut eq = equivalence();
    let mut r = TestRng::new(14);
    let mut args: Vec<(u32, u32)> = Vec::new();
    for x in [0, 1, 0x8000_0000, u32::MAX, 0x1234_5678, 0xdead_beef] {
        for n in (0..=70).chain([u32::MAX, 0x8000_0000, 0x8000_001f]) {
            args.push((x, n));
        }
    }
    while args.len() < 1 << 16 {
        args.push((r.next_u32(), r.next_u32() >> (r.next_u32() % 32)));
    }
    assert_equivalent(&mut eq, "shifts", &args, |_, &(x, n)| (kernel::shifts(x, n),), Tolerance::EXACT);
    let xs: Vec<(u32,)> = args.iter().map(|&(x, n)| (x ^ n,)).collect();
    assert_equivalent(&mut eq, "literal_shifts", &xs, |_, &(x,)| (kernel::literal_shifts(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "wrapping_ops", &args, |_, &(a, b)| (kernel::wrapping_ops(a, b),), Tolerance::EXACT);
}

#[test]
fn float_rounding_and_classification() {
    let mut eq = equivalence();
    let xs: Vec<(f32,)> = floats_with_specials(1 << 16, 15, any_float)
        .into_iter()
        .chain(floats_with_specials(1 << 14, 16, |r| r.range(-8.0, 8.0)))
        .map(|x| (x,))
        .collect();
    assert_equivalent(&mut eq, "rounding", &xs, |_, &(x,)| (kernel::rounding(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "floor_ceil_abs", &xs, |_, &(x,)| (kernel::floor_ceil_abs(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "classify", &xs, |_, &(x,)| (kernel::classify(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "to_bits", &xs, |_, &(x,)| (kernel::to_bits(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "specials", &xs, |_, &(x,)| (kernel::specials(x),), Tolerance::EXACT);
}

#[test]
fn float_remainder_truncates() {
    let mut eq = equivalence();
    let mut r = TestRng::new(17);
    let mut pairs: Vec<(f32, f32)> = vec![(5.5, 2.0), (-5.5, 2.0), (5.5, -2.0), (-5.5, -2.0), (-0.0, 1.0), (1.0, 0.5)];
    while pairs.len() < 1 << 16 {
        let a = r.range(-1000.0, 1000.0);
        let b = r.range(0.01, 10.0) * if r.f32() < 0.5 { -1.0 } else { 1.0 };
        pairs.push((a, b));
    }
    // GLSL's a - b * trunc(a / b) rounds the quotient; Rust's % is exact. Quotients here stay
    // below 2^17, so the difference is a few ULP of b * quotient (measured and printed).
    let outcome = assert_equivalent(
        &mut eq,
        "fmod",
        &pairs,
        |_, &(a, b)| (kernel::fmod(a, b),),
        Tolerance::EXACT.with_absolute(2e-4),
    );
    // The sign of the result is the dividend's (truncation, not GLSL mod's floor).
    for backend in Backend::GPU {
        let gpu = outcome.output(backend).unwrap();
        for (&(a, b), &(m,)) in pairs.iter().zip(gpu) {
            assert!(m == 0.0 || m.is_sign_negative() == a.is_sign_negative(), "{a} % {b} = {m} on {backend}");
        }
    }
}

/// Runs `function` on subnormal inputs and asserts that GL either keeps them (the CPU's answer)
/// or flushes them to zero: its answer is then the CPU's for +0 or -0 (outputs may flush too).
/// Returns how many inputs each GPU runtime flushed.
fn assert_flushed_or_kept<I, O>(
    eq: &mut Equivalence,
    function: &str,
    inputs: &[f32],
    make: impl Fn(f32) -> I + Sync,
    f: impl Fn(&I) -> O + Sync,
    tolerance: Tolerance,
) -> [usize; Backend::GPU.len()]
where
    I: Values + Sync,
    O: Values + Send,
{
    let tolerance = tolerance.flushing_subnormals();
    let args: Vec<I> = inputs.iter().map(|&x| make(x)).collect();
    let outcome = eq.run(function, &args, |_, i| f(i), tolerance).unwrap_or_else(|e| panic!("{function}: {e}"));
    report(&outcome);
    let words = |o: &O| {
        let mut w = Vec::new();
        o.push_words(&mut w);
        w
    };
    let layout = O::layout();
    Backend::GPU.map(|backend| {
    let gl = outcome.output(backend).unwrap();
    let mismatched = &outcome.comparison(backend).unwrap().mismatched;
    for &i in mismatched {
        let got = words(&gl[i]);
        // Flushing is per operation (llvmpipe's `ceil` flushes its input, `abs` and negation
        // keep the bits): each output word is the CPU's for the input or for a zero.
        let references = [inputs[i], 0.0, -0.0].map(|x| words(&f(&make(x))));
        for (k, word) in layout.iter().enumerate() {
            let matches = references.iter().any(|want| {
                let one = std::slice::from_ref(word);
                tracer::backend::harness::compare_words(backend, one, &want[k..=k], &got[k..=k], tolerance)
                    .is_equivalent()
            });
            assert!(
                matches,
                "{function}({:e}) word `{}`: {backend}'s {:#x} is neither the CPU's for the input nor for a zero ({:x?})",
                inputs[i], word.path, got[k], references
            );
        }
    }
    mismatched.len()
    })
}

#[test]
fn subnormals_flush_to_zero_or_are_kept() {
    let mut eq = equivalence();
    let xs = subnormals(1 << 12, 22);
    let exact = Tolerance::EXACT;
    let flushed = [
        assert_flushed_or_kept(&mut eq, "to_bits", &xs, |x| (x,), |&(x,)| (kernel::to_bits(x),), exact),
        assert_flushed_or_kept(&mut eq, "classify", &xs, |x| (x,), |&(x,)| (kernel::classify(x),), exact),
        assert_flushed_or_kept(&mut eq, "rounding", &xs, |x| (x,), |&(x,)| (kernel::rounding(x),), exact),
        assert_flushed_or_kept(&mut eq, "floor_ceil_abs", &xs, |x| (x,), |&(x,)| (kernel::floor_ceil_abs(x),), exact),
        assert_flushed_or_kept(&mut eq, "float_to_i32", &xs, |x| (x,), |&(x,)| (kernel::float_to_i32(x),), exact),
        assert_flushed_or_kept(&mut eq, "specials", &xs, |x| (x,), |&(x,)| (kernel::specials(x),), exact),
        assert_flushed_or_kept(
            &mut eq,
            "safe_inverse",
            &xs,
            |x| (Vec3::new(x, 1.0, -x),),
            |&(d,)| (intersect::safe_inverse(d),),
            Tolerance::ulps(3),
        ),
    ];
    println!("subnormal inputs flushed by {:?}, per function: {flushed:?} of {}", Backend::GPU, xs.len());
}

/// `min`/`max` with NaN are not defined by the DSL (kernels avoid them): without NaN they are
/// exact; with NaN, a GPU may return either operand or NaN, but nothing else.
#[test]
fn min_max_with_and_without_nan() {
    let mut eq = equivalence();
    let mut r = TestRng::new(18);
    let xs = floats_with_specials(1 << 12, 19, any_float);
    let mut pairs: Vec<(f32, f32)> = xs.iter().flat_map(|&a| [(a, f32::NAN), (f32::NAN, a)]).collect();
    while pairs.len() < 1 << 15 {
        pairs.push((any_float(&mut r), any_float(&mut r)));
    }
    let outcome = eq.run("min_max", &pairs, |_, &(a, b)| (kernel::min_max(a, b),), Tolerance::EXACT).expect("runs");
    report(&outcome);
    for backend in Backend::GPU {
        let gl = outcome.output(backend).unwrap();
        let mut nan_cases_differing = 0;
        for &i in &outcome.comparison(backend).unwrap().mismatched {
            let (a, b) = pairs[i];
            let is_either = |m: f32| m.to_bits() == a.to_bits() || m.to_bits() == b.to_bits() || m.is_nan();
            let (got,) = gl[i];
            assert!(
                a.is_nan() || b.is_nan() || (a == 0.0 && b == 0.0),
                "min/max({a}, {b}) without NaN differs: {backend} {got}"
            );
            // +0 and -0 compare equal, so min/max may return either zero.
            assert!(
                is_either(got.x) && is_either(got.y),
                "min/max({a}, {b}) on {backend} = {got}: neither operand nor NaN"
            );
            nan_cases_differing += 1;
        }
        let zeros = pairs.iter().filter(|(a, b)| *a == 0.0 && *b == 0.0).count();
        println!(
            "min_max: {nan_cases_differing} NaN cases where {backend} differs from Rust (allowed); {zeros} zero pairs"
        );
    }
}
