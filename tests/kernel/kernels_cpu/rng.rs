//! The RNG (wang hash, xorshift32, `random_float`) against reference implementations written
//! independently, known values and edge cases.

use crate::common;

use common::{assert_chi_square, assert_within_sigmas, mean_variance, TestRng};
use tracer::kernel::rng::{pixel_jitter, pixel_seed, random_float, random_u32, wang_hash};

/// Thomas Wang's hash written independently of the kernel: `* 9` as `+ (k << 3)`.
fn reference_wang_hash(key: u32) -> u32 {
    let mut k = key ^ 61 ^ (key >> 16);
    k = k.wrapping_add(k << 3);
    k ^= k >> 4;
    k = k.wrapping_mul(0x27d4_eb2d);
    k ^ (k >> 15)
}

/// Marsaglia's xorshift32 (13, 17, 5), written in 64-bit arithmetic with explicit masking.
fn reference_xorshift32(x: u32) -> u32 {
    let mut x = x as u64;
    x ^= (x << 13) & 0xffff_ffff;
    x ^= x >> 17;
    x ^= (x << 5) & 0xffff_ffff;
    x as u32
}

/// Inverse of `x ^= x >> k`.
fn unxorshift_right(y: u32, k: u32) -> u32 {
    let mut x = y;
    for _ in 0..32 / k + 1 {
        x = y ^ (x >> k);
    }
    x
}

/// Inverse of `x ^= x << k`.
fn unxorshift_left(y: u32, k: u32) -> u32 {
    let mut x = y;
    for _ in 0..32 / k + 1 {
        x = y ^ (x << k);
    }
    x
}

/// The multiplicative inverse of an odd number modulo 2^32 (Newton's iteration).
fn inverse_mod_2_32(a: u32) -> u32 {
    let mut x = a; // correct to 3 bits for odd a
    for _ in 0..5 {
        x = x.wrapping_mul(2u32.wrapping_sub(a.wrapping_mul(x)));
    }
    x
}

/// The state whose xorshift32 successor is `y`.
fn xorshift32_predecessor(y: u32) -> u32 {
    unxorshift_left(unxorshift_right(unxorshift_left(y, 5), 17), 13)
}

/// The key whose Wang hash is `h` (every step of the hash is a bijection).
fn inverse_wang_hash(h: u32) -> u32 {
    let mut k = unxorshift_right(h, 15);
    k = k.wrapping_mul(inverse_mod_2_32(0x27d4_eb2d));
    k = unxorshift_right(k, 4);
    k = k.wrapping_mul(inverse_mod_2_32(9));
    let y = k ^ 61; // = key ^ (key >> 16)
    y ^ (y >> 16)
}

#[test]
fn wang_hash_known_values() {
    // By hand: wang_hash(61): 61 ^ 61 ^ 0 = 0, and every later step keeps 0.
    assert_eq!(wang_hash(61), 0);
    // By hand: wang_hash(0): 0 ^ 61 = 61; * 9 = 549; 549 ^ (549 >> 4) = 549 ^ 34 = 519;
    // 519 * 0x27d4eb2d mod 2^32 = 3232286779; ^ (>> 15 = 98641) = 3232319850.
    assert_eq!(wang_hash(0), 3_232_319_850);
    // Computed with an independent (Python, arbitrary precision) implementation.
    assert_eq!(wang_hash(1), 663_891_101);
    assert_eq!(wang_hash(2), 3_329_832_309);
    assert_eq!(wang_hash(12345), 232_713_235);
    assert_eq!(wang_hash(0x8000_0000), 2_903_943_700);
    assert_eq!(wang_hash(u32::MAX), 1_895_078_355);
}

#[test]
fn wang_hash_matches_reference() {
    let mut rng = TestRng::new(1);
    let edge = [0, 1, 60, 61, 62, 0xffff, 0x1_0000, 0x7fff_ffff, 0x8000_0000, u32::MAX - 1, u32::MAX];
    for key in edge.into_iter().chain((0..100_000).map(|_| rng.next_u32())).chain(0..10_000) {
        assert_eq!(wang_hash(key), reference_wang_hash(key), "key {key:#x}");
    }
    // The inverse used below is right (so the hash is a bijection and 61 is the only zero).
    for _ in 0..10_000 {
        let key = rng.next_u32();
        assert_eq!(inverse_wang_hash(wang_hash(key)), key);
    }
    assert_eq!(inverse_wang_hash(0), 61);
}

#[test]
fn xorshift32_known_values() {
    // Marsaglia's xorshift32 (13, 17, 5) from state 1. By hand: 1 ^ (1 << 13) = 8193;
    // >> 17 is 0; 8193 ^ (8193 << 5 = 262176) = 270369.
    let mut state = 1;
    let expected = [270_369, 67_634_689, 2_647_435_461, 307_599_695, 2_398_689_233];
    for e in expected {
        let out = random_u32(&mut state);
        assert_eq!(out, e);
        assert_eq!(state, e, "the returned value is the new state");
    }
}

#[test]
fn xorshift32_matches_reference() {
    let mut rng = TestRng::new(2);
    for _ in 0..100_000 {
        let s = rng.next_u32() | 1;
        let mut state = s;
        let out = random_u32(&mut state);
        assert_eq!(out, reference_xorshift32(s), "state {s:#x}");
        assert_eq!(xorshift32_predecessor(out), s);
    }
    // A long stream never reaches zero and agrees step by step.
    let (mut state, mut reference) = (pixel_seed(7, 3), pixel_seed(7, 3));
    for i in 0..1_000_000 {
        reference = reference_xorshift32(reference);
        assert_eq!(random_u32(&mut state), reference, "step {i}");
        assert_ne!(state, 0);
    }
}

#[test]
fn pixel_seed_is_never_zero() {
    // wang_hash is a bijection with wang_hash(61) == 0: every (pixel, frame) pair summing to
    // 61 (mod 2^32) takes the replacement path.
    for (pixel, frame) in [(61, 0), (0, 61), (30, 31), (62, u32::MAX), (u32::MAX, 62), (61u32.wrapping_sub(1000), 1000)]
    {
        assert_eq!(wang_hash(pixel.wrapping_add(frame)), 0);
        let seed = pixel_seed(pixel, frame);
        assert_ne!(seed, 0, "pixel {pixel} frame {frame}");
        // The stream from it does not stick at zero either.
        let mut state = seed;
        assert_ne!(random_u32(&mut state), 0);
    }
    // Elsewhere it is the hash itself.
    let mut rng = TestRng::new(3);
    for _ in 0..100_000 {
        let (pixel, frame) = (rng.next_u32() % (4096 * 4096), rng.next_u32());
        let seed = pixel_seed(pixel, frame);
        assert_ne!(seed, 0);
        let h = reference_wang_hash(pixel.wrapping_add(frame));
        if h != 0 {
            assert_eq!(seed, h);
        }
    }
    // Neighbouring pixels of one frame get distinct seeds (the hash is a bijection).
    let seeds: std::collections::HashSet<u32> = (0..640 * 480).map(|p| pixel_seed(p, 12345)).collect();
    assert_eq!(seeds.len(), 640 * 480);
}

/// `random_float` from the state whose next xorshift output is `output`.
fn float_for_output(output: u32) -> f32 {
    let mut state = xorshift32_predecessor(output);
    let f = random_float(&mut state);
    assert_eq!(state, output);
    f
}

#[test]
fn random_float_edge_cases_stay_below_one() {
    let largest = 1.0 - 2f32.powi(-24);
    let cases = [
        (u32::MAX, largest),
        (u32::MAX - 1, largest),
        (0xffff_ff80, largest),
        (0xffff_ff00, largest),
        (0xffff_feff, 1.0 - 2f32.powi(-23)),
        (0xffff_fe00, 1.0 - 2f32.powi(-23)),
        (0x8000_0000, 0.5),
        (0x7fff_ffff, 0.5 - 2f32.powi(-24)),
        (0x0000_01ff, 2f32.powi(-24)),
        (0x0000_0100, 2f32.powi(-24)),
        (0x0000_00ff, 0.0),
        (0x0000_0001, 0.0),
    ];
    for (output, expected) in cases {
        let f = float_for_output(output);
        assert_eq!(f, expected, "output {output:#x}");
        assert!((0.0..1.0).contains(&f));
    }
    // Outputs just below 2^32: the float is the top 24 bits, never rounded up to 1.0.
    for output in (u32::MAX - 100_000)..=u32::MAX {
        assert!(float_for_output(output) < 1.0, "output {output:#x}");
    }
}

#[test]
fn random_float_covers_all_24_bit_values_in_order() {
    // For each of the 2^24 top-bit patterns (low byte all ones, the worst case for rounding),
    // the float is exactly pattern * 2^-24: in [0, 1), distinct and increasing.
    let mut previous = -1.0f32;
    for top in 0..(1u32 << 24) {
        let f = float_for_output((top << 8) | 0xff);
        assert!(f > previous && f < 1.0, "pattern {top:#x}: {f} after {previous}");
        assert_eq!(f, top as f32 / 16_777_216.0);
        previous = f;
    }
}

#[test]
fn random_float_mean_and_variance() {
    const N: usize = 1_000_000;
    let mut state = pixel_seed(1234, 99);
    let draws: Vec<f64> = (0..N).map(|_| random_float(&mut state) as f64).collect();
    assert!(draws.iter().all(|x| (0.0..1.0).contains(x)));
    let (mean, variance, n) = mean_variance(draws.iter().copied());
    // Uniform [0, 1): mean 1/2 (variance of one draw 1/12); variance 1/12, and the variance
    // of one draw's squared deviation is E[(X - 1/2)^4] - (1/12)^2 = 1/80 - 1/144 = 1/180.
    let z_mean = assert_within_sigmas("mean", mean, 0.5, 1.0 / 12.0, n, 5.0);
    let z_var = assert_within_sigmas("variance", variance, 1.0 / 12.0, 1.0 / 180.0, n, 5.0);
    // And the histogram is flat (64 bins).
    let mut bins = [0u64; 64];
    for x in &draws {
        bins[(x * 64.0) as usize] += 1;
    }
    let chi2 = assert_chi_square("random_float histogram", &bins, &[N as f64 / 64.0; 64]);
    // Successive pairs are not correlated.
    let pairs = draws.windows(2).map(|w| (w[0] - 0.5) * (w[1] - 0.5));
    let (cov, _, n) = mean_variance(pairs);
    let z_cov = assert_within_sigmas("lag-1 covariance", cov, 0.0, 1.0 / 144.0, n, 5.0);
    eprintln!(
        "random_float: mean {mean:.5} ({z_mean:+.2} se), variance {variance:.5} ({z_var:+.2} se), \
         chi2 {chi2:.1} (63 dof), lag-1 covariance {z_cov:+.2} se"
    );
}

/// `pixel_jitter`: a pixel's successive samples spread evenly over it. Its first 16 film
/// positions fall into nearly all 16 cells of a 4x4 grid (independent uniform positions fill
/// 10.3 on average), the same pixel of another render (another seed) has another pattern, and
/// over many pixels the positions are uniform (each pixel's offset is random).
#[test]
fn pixel_jitter_stratifies_each_pixels_samples() {
    let frame_seed = |frame: u32, seed: u32| tracer::backend::frame_seed(frame, seed);
    let cells = |pixel: u32, seed: u32| {
        let mut cells = [false; 16];
        for frame in 0..16 {
            let p = pixel_jitter(pixel, frame_seed(frame, seed), frame);
            assert!(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0, "{p}");
            cells[(p.y * 4.0) as usize * 4 + (p.x * 4.0) as usize] = true;
        }
        cells.iter().filter(|c| **c).count()
    };
    let pixels = 2000;
    let mean = (0..pixels).map(|i| cells(i * 7919, 3) as f64).sum::<f64>() / pixels as f64;
    eprintln!("a pixel's first 16 samples occupy {mean:.2} of 16 cells on average");
    assert!(mean >= 13.5, "{mean:.2} of 16 cells: the samples are not stratified");
    // Another seed, another pattern; the same seed, the same one.
    let first = |seed: u32| pixel_jitter(42, frame_seed(0, seed), 0);
    assert_ne!(first(3), first(4));
    assert_eq!(first(3), first(3));
    // Uniform over pixels: each frame's positions, over many pixels, have mean 1/2 and variance 1/12.
    for frame in [0, 1, 15] {
        let xs: Vec<f64> = (0..20000).map(|i| pixel_jitter(i, frame_seed(frame, 9), frame).x as f64).collect();
        let (m, v, _) = mean_variance(xs);
        assert!((m - 0.5).abs() < 0.01 && (v - 1.0 / 12.0).abs() < 0.003, "frame {frame}: mean {m}, variance {v}");
    }
}
