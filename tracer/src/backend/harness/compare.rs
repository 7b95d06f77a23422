//! Comparing a backend's output words with the CPU's under a stated [`Tolerance`].

use std::fmt;

use lightport_codegen::types::Scalar;

use super::{Backend, HarnessWord};

/// How far a float output may be from the reference. Integer and bool words must be equal.
///
/// Two floats match when their bits are equal, when both are NaN (any payload: NaN matches NaN
/// by class), or — both finite — when they are at most `ulps` representable values apart (+0
/// and -0 count as one apart), or `|a - b| <= relative * max(|a|, |b|)`, or
/// `|a - b| <= absolute`. Infinities match only themselves. With `flush_subnormals`, a
/// subnormal reference also matches a zero of either sign: GPUs may flush subnormals to zero
/// (GLSL ES 3.00 leaves their support optional; llvmpipe flushes them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    pub ulps: u32,
    pub relative: f32,
    pub absolute: f32,
    pub flush_subnormals: bool,
}

impl Tolerance {
    /// Bit-exact floats (NaN still matches NaN).
    pub const EXACT: Tolerance = Tolerance { ulps: 0, relative: 0.0, absolute: 0.0, flush_subnormals: false };

    pub const fn ulps(ulps: u32) -> Tolerance {
        Tolerance { ulps, ..Tolerance::EXACT }
    }

    /// Also accept zero where the reference is subnormal.
    pub const fn flushing_subnormals(self) -> Tolerance {
        Tolerance { flush_subnormals: true, ..self }
    }

    pub const fn with_absolute(self, absolute: f32) -> Tolerance {
        Tolerance { absolute, ..self }
    }

    pub const fn with_relative(self, relative: f32) -> Tolerance {
        Tolerance { relative, ..self }
    }

    /// Whether `got` matches the reference `want`.
    pub fn floats_match(&self, want: f32, got: f32) -> bool {
        if want.to_bits() == got.to_bits() || (want.is_nan() && got.is_nan()) {
            return true;
        }
        if !want.is_finite() || !got.is_finite() {
            return false;
        }
        if self.flush_subnormals && want.is_subnormal() && got == 0.0 {
            return true;
        }
        let diff = (want - got).abs();
        // The bounds are inclusive but a zero bound allows nothing: +0 and -0 differ by 0.0.
        ulp_distance(want, got) <= u64::from(self.ulps)
            || (self.relative > 0.0 && diff <= self.relative * want.abs().max(got.abs()))
            || (self.absolute > 0.0 && diff <= self.absolute)
    }
}

impl fmt::Display for Tolerance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if (self.ulps, self.relative, self.absolute) == (0, 0.0, 0.0) {
            f.write_str("bit-exact")?;
        } else {
            write!(f, "{} ULP", self.ulps)?;
        }
        if self.relative > 0.0 {
            write!(f, " or relative {:e}", self.relative)?;
        }
        if self.absolute > 0.0 {
            write!(f, " or absolute {:e}", self.absolute)?;
        }
        if self.flush_subnormals {
            f.write_str(", subnormals may flush to 0")?;
        }
        Ok(())
    }
}

/// Representable f32 values between `a` and `b` (not NaN): the distance between their
/// positions on the ordered line of floats, where -0.0 and +0.0 are neighbours.
pub fn ulp_distance(a: f32, b: f32) -> u64 {
    fn position(x: f32) -> i64 {
        let bits = x.to_bits();
        let magnitude = i64::from(bits & 0x7fff_ffff);
        if bits >> 31 == 1 {
            -magnitude - 1
        } else {
            magnitude
        }
    }
    position(a).abs_diff(position(b))
}

/// One output word of one invocation that did not match.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    pub invocation: usize,
    /// The word's path in the generated layout, e.g. `return.t`.
    pub path: String,
    pub scalar: Scalar,
    pub reference: u32,
    pub got: u32,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let show = |w: u32| match self.scalar {
            Scalar::F32 => format!("{:e} ({w:#010x})", f32::from_bits(w)),
            Scalar::I32 => format!("{}", w as i32),
            _ => format!("{w} ({w:#x})"),
        };
        write!(f, "invocation {} `{}`: CPU {} vs {}", self.invocation, self.path, show(self.reference), show(self.got))
    }
}

/// One backend's outputs against the CPU reference.
#[derive(Clone, Debug)]
pub struct Comparison {
    pub backend: Backend,
    pub tolerance: Tolerance,
    pub invocations: usize,
    /// Invocations with at least one word out of tolerance, in order.
    pub mismatched: Vec<usize>,
    /// The first mismatching words (at most [`Comparison::EXAMPLES`]).
    pub examples: Vec<Mismatch>,
    /// The largest ULP distance among float words where both sides are finite (including
    /// those within tolerance, excluding subnormals flushed to zero where the tolerance allows
    /// it): how close the backends really are.
    pub max_ulps: u64,
    /// The largest absolute difference among the same words.
    pub max_abs: f64,
    /// Float words that are not bit-identical (but may be within tolerance).
    pub inexact_floats: usize,
}

impl Comparison {
    pub const EXAMPLES: usize = 8;

    pub fn is_equivalent(&self) -> bool {
        self.mismatched.is_empty()
    }
}

impl fmt::Display for Comparison {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} vs CPU: {} of {} invocations out of tolerance ({}); max {} ULP / {:e} absolute, {} float words not bit-identical",
            self.backend,
            self.mismatched.len(),
            self.invocations,
            self.tolerance,
            self.max_ulps,
            self.max_abs,
            self.inexact_floats
        )?;
        for m in &self.examples {
            write!(f, "\n  {m}")?;
        }
        Ok(())
    }
}

/// Compares `got` with `reference` (both `invocations * layout.len()` words).
pub fn compare_words(
    backend: Backend,
    layout: &[HarnessWord],
    reference: &[u32],
    got: &[u32],
    tolerance: Tolerance,
) -> Comparison {
    let per = layout.len().max(1);
    let invocations = reference.len() / per;
    let mut c = Comparison {
        backend,
        tolerance,
        invocations,
        mismatched: Vec::new(),
        examples: Vec::new(),
        max_ulps: 0,
        max_abs: 0.0,
        inexact_floats: 0,
    };
    for (i, (want, have)) in reference.chunks(per).zip(got.chunks(per)).enumerate() {
        let mut bad = false;
        for ((word, &w), &g) in layout.iter().zip(want).zip(have) {
            let ok = if word.scalar == Scalar::F32 {
                let (a, b) = (f32::from_bits(w), f32::from_bits(g));
                if w != g && !(a.is_nan() && b.is_nan()) {
                    c.inexact_floats += 1;
                    let flushed = tolerance.flush_subnormals && a.is_subnormal() && b == 0.0;
                    if a.is_finite() && b.is_finite() && !flushed {
                        c.max_ulps = c.max_ulps.max(ulp_distance(a, b));
                        c.max_abs = c.max_abs.max((f64::from(a) - f64::from(b)).abs());
                    }
                }
                tolerance.floats_match(a, b)
            } else {
                w == g
            };
            if !ok {
                bad = true;
                if c.examples.len() < Comparison::EXAMPLES {
                    c.examples.push(Mismatch {
                        invocation: i,
                        path: word.path.clone(),
                        scalar: word.scalar,
                        reference: w,
                        got: g,
                    });
                }
            }
        }
        if bad {
            c.mismatched.push(i);
        }
    }
    c
}
