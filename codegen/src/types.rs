//! Codegen's view of kernel types, and the table of built-in (glam, f32, integer) methods.

use std::fmt;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Scalar {
    F32,
    I32,
    U32,
    Bool,
    /// Rust's index type. Kernels only use it to index arrays; on GPUs it is a u32.
    USize,
}

#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub enum Ty {
    Scalar(Scalar),
    Vector(Scalar, u8),
    Struct(String),
    Array(Box<Ty>, u32),
    /// `Texels<Vec4>` / `Texels<UVec4>`: a data texture in a resource struct.
    Texels(Box<Ty>),
    /// `Storage<Vec4|UVec4|u32|f32>`: a read-write array of a compute module's resources.
    Storage(Box<Ty>),
    /// `Atomics`: `u32` counters of a compute module's resources.
    Atomics,
    /// A `#[resources]` struct (always behind `&`).
    Resource(String),
    /// `&mut T`: a parameter or argument that aliases a caller's variable.
    RefMut(Box<Ty>),
    #[default]
    Unit,
    /// The type of `return`, `break` and `continue`: fits anywhere.
    Never,
    /// An integer literal whose type is not yet known (rustc's `{integer}`).
    IntVar(u32),
}

pub const F32: Ty = Ty::Scalar(Scalar::F32);
pub const I32: Ty = Ty::Scalar(Scalar::I32);
pub const U32: Ty = Ty::Scalar(Scalar::U32);
pub const BOOL: Ty = Ty::Scalar(Scalar::Bool);
pub const USIZE: Ty = Ty::Scalar(Scalar::USize);

impl Ty {
    pub fn is_int(&self) -> bool {
        matches!(self, Ty::Scalar(Scalar::I32 | Scalar::U32 | Scalar::USize) | Ty::IntVar(_))
    }

    /// The element scalar of a scalar or vector type.
    pub fn scalar(&self) -> Option<Scalar> {
        match self {
            Ty::Scalar(s) | Ty::Vector(s, _) => Some(*s),
            Ty::IntVar(_) => Some(Scalar::I32),
            _ => None,
        }
    }

    /// Strips one `&mut`: Rust auto-dereferences for field access, indexing and methods.
    pub fn strip_ref(&self) -> &Ty {
        match self {
            Ty::RefMut(inner) => inner,
            t => t,
        }
    }

    /// Parses a glam/scalar type name.
    pub fn builtin(name: &str) -> Option<Ty> {
        Some(match name {
            "f32" => F32,
            "i32" => I32,
            "u32" => U32,
            "bool" => BOOL,
            "usize" => USIZE,
            "Vec2" => Ty::Vector(F32_, 2),
            "Vec3" => Ty::Vector(F32_, 3),
            "Vec4" => Ty::Vector(F32_, 4),
            "IVec2" => Ty::Vector(I32_, 2),
            "IVec3" => Ty::Vector(I32_, 3),
            "IVec4" => Ty::Vector(I32_, 4),
            "UVec2" => Ty::Vector(U32_, 2),
            "UVec3" => Ty::Vector(U32_, 3),
            "UVec4" => Ty::Vector(U32_, 4),
            _ => return None,
        })
    }
}

// Short aliases for the table above.
const F32_: Scalar = Scalar::F32;
const I32_: Scalar = Scalar::I32;
const U32_: Scalar = Scalar::U32;

impl fmt::Display for Ty {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ty::Scalar(s) => write!(f, "{}", scalar_rust(*s)),
            Ty::Vector(s, n) => {
                let prefix = match s {
                    Scalar::F32 => "",
                    Scalar::I32 => "I",
                    Scalar::U32 => "U",
                    _ => "?",
                };
                write!(f, "{prefix}Vec{n}")
            }
            Ty::Struct(n) | Ty::Resource(n) => write!(f, "{n}"),
            Ty::Array(t, n) => write!(f, "[{t}; {n}]"),
            Ty::Texels(t) => write!(f, "Texels<{t}>"),
            Ty::Storage(t) => write!(f, "Storage<{t}>"),
            Ty::Atomics => write!(f, "Atomics"),
            Ty::RefMut(t) => write!(f, "&mut {t}"),
            Ty::Unit => write!(f, "()"),
            Ty::Never => write!(f, "!"),
            Ty::IntVar(_) => write!(f, "{{integer}}"),
        }
    }
}

pub fn scalar_rust(s: Scalar) -> &'static str {
    match s {
        Scalar::F32 => "f32",
        Scalar::I32 => "i32",
        Scalar::U32 => "u32",
        Scalar::Bool => "bool",
        Scalar::USize => "usize",
    }
}

/// The result type of a built-in method, or `None` when the receiver has no such method in
/// the subset. `args` are the argument types (already resolved where possible).
pub fn method_result(recv: &Ty, method: &str, args: &[Ty]) -> Option<Ty> {
    let float_scalar = *recv == F32;
    let int_scalar = recv.is_int();
    let vector = matches!(recv, Ty::Vector(..));
    let fvec = matches!(recv, Ty::Vector(Scalar::F32, _));
    let n = match recv {
        Ty::Vector(_, n) => *n,
        _ => 1,
    };
    let arity = args.len();
    let same = Some(recv.clone());
    match (method, arity) {
        (
            "sqrt" | "sin" | "cos" | "tan" | "asin" | "acos" | "atan" | "exp" | "exp2" | "ln" | "log2" | "recip"
            | "to_radians" | "to_degrees",
            0,
        ) if float_scalar => same,
        ("exp" | "recip", 0) if fvec => same,
        ("floor" | "ceil" | "trunc" | "fract", 0) if float_scalar || fvec => same,
        ("round" | "signum", 0) if float_scalar => same,
        ("abs", 0) if float_scalar || fvec || *recv == I32 || matches!(recv, Ty::Vector(Scalar::I32, _)) => same,
        ("atan2" | "powf", 1) if float_scalar => same,
        ("powf", 1) if fvec => same,
        ("min" | "max", 1) if recv.scalar().is_some() && *recv != BOOL => same,
        ("clamp", 2) if recv.scalar().is_some() && *recv != BOOL => same,
        ("to_bits", 0) if float_scalar => Some(U32),
        ("is_nan" | "is_finite" | "is_infinite", 0) if float_scalar => Some(BOOL),
        ("wrapping_add" | "wrapping_sub" | "wrapping_mul", 1) if int_scalar => same,
        ("wrapping_neg", 0) if int_scalar => same,
        ("wrapping_shl" | "wrapping_shr", 1) if int_scalar => same,
        ("dot", 1) if vector => Some(Ty::Scalar(recv.scalar()?)),
        ("cross", 1) if fvec && n == 3 => same,
        ("length" | "length_squared", 0) | ("distance", 1) if fvec => Some(F32),
        ("normalize", 0) if fvec => same,
        ("reflect", 1) if fvec => same,
        ("lerp", 2) if fvec => same,
        ("min_element" | "max_element" | "element_sum" | "element_product", 0) if vector => {
            Some(Ty::Scalar(recv.scalar()?))
        }
        ("extend", 1) if vector && n < 4 => Some(Ty::Vector(recv.scalar()?, n + 1)),
        ("truncate", 0) if vector && n > 2 => Some(Ty::Vector(recv.scalar()?, n - 1)),
        ("xy" | "xz" | "yz", 0) if vector => Some(Ty::Vector(recv.scalar()?, 2)),
        ("xyz", 0) if vector && n >= 3 => Some(Ty::Vector(recv.scalar()?, 3)),
        ("as_vec2" | "as_vec3" | "as_vec4", 0) if vector => Some(Ty::Vector(Scalar::F32, n)),
        ("as_uvec2" | "as_uvec3" | "as_uvec4", 0) if vector => Some(Ty::Vector(Scalar::U32, n)),
        ("as_ivec2" | "as_ivec3" | "as_ivec4", 0) if vector => Some(Ty::Vector(Scalar::I32, n)),
        ("fetch", 1) => match recv {
            Ty::Texels(t) => Some((**t).clone()),
            _ => None,
        },
        ("load", 1) => match recv {
            Ty::Storage(t) => Some((**t).clone()),
            _ => None,
        },
        ("store", 2) if matches!(recv, Ty::Storage(_)) => Some(Ty::Unit),
        ("atomic_add" | "atomic_sub" | "atomic_min" | "atomic_max" | "atomic_exchange", 2) if *recv == Ty::Atomics => {
            Some(U32)
        }
        ("atomic_load", 1) if *recv == Ty::Atomics => Some(U32),
        ("atomic_store", 2) if *recv == Ty::Atomics => Some(Ty::Unit),
        _ => None,
    }
}

/// Constants reached through a type path: `f32::MAX`, `f32::consts::PI`, `Vec3::ZERO`, ...
/// Returns the type and the value as `f32`/`u32`/`i32` bits for scalars, or the per-component
/// values for vectors.
pub fn assoc_const(path: &[String]) -> Option<(Ty, ConstValue)> {
    let p: Vec<&str> = path.iter().map(String::as_str).collect();
    use ConstValue as C;
    Some(match p.as_slice() {
        ["f32", "consts", name] => (
            F32,
            C::F32(match *name {
                "PI" => std::f32::consts::PI,
                "TAU" => std::f32::consts::TAU,
                "E" => std::f32::consts::E,
                "FRAC_1_PI" => std::f32::consts::FRAC_1_PI,
                "FRAC_2_PI" => std::f32::consts::FRAC_2_PI,
                "FRAC_PI_2" => std::f32::consts::FRAC_PI_2,
                "FRAC_PI_3" => std::f32::consts::FRAC_PI_3,
                "FRAC_PI_4" => std::f32::consts::FRAC_PI_4,
                "FRAC_PI_6" => std::f32::consts::FRAC_PI_6,
                "FRAC_PI_8" => std::f32::consts::FRAC_PI_8,
                "SQRT_2" => std::f32::consts::SQRT_2,
                "FRAC_1_SQRT_2" => std::f32::consts::FRAC_1_SQRT_2,
                "LN_2" => std::f32::consts::LN_2,
                _ => return None,
            }),
        ),
        ["f32", name] => (
            F32,
            C::F32(match *name {
                "MAX" => f32::MAX,
                "MIN" => f32::MIN,
                "MIN_POSITIVE" => f32::MIN_POSITIVE,
                "EPSILON" => f32::EPSILON,
                "INFINITY" => f32::INFINITY,
                "NEG_INFINITY" => f32::NEG_INFINITY,
                "NAN" => f32::NAN,
                _ => return None,
            }),
        ),
        ["u32", "MAX"] => (U32, C::U32(u32::MAX)),
        ["u32", "MIN"] => (U32, C::U32(0)),
        ["i32", "MAX"] => (I32, C::I32(i32::MAX)),
        ["i32", "MIN"] => (I32, C::I32(i32::MIN)),
        [ty, name] => {
            let t = Ty::builtin(ty)?;
            let Ty::Vector(s, n) = t else { return None };
            let one = |i: usize| -> Vec<f64> { (0..n as usize).map(|k| if k == i { 1.0 } else { 0.0 }).collect() };
            let comps: Vec<f64> = match *name {
                "ZERO" => vec![0.0; n as usize],
                "ONE" => vec![1.0; n as usize],
                "NEG_ONE" if s != Scalar::U32 => vec![-1.0; n as usize],
                "X" => one(0),
                "Y" => one(1),
                "Z" if n >= 3 => one(2),
                "W" if n >= 4 => one(3),
                "NEG_X" if s != Scalar::U32 => one(0).into_iter().map(|v| -v).collect(),
                "NEG_Y" if s != Scalar::U32 => one(1).into_iter().map(|v| -v).collect(),
                "NEG_Z" if s != Scalar::U32 && n >= 3 => one(2).into_iter().map(|v| -v).collect(),
                _ => return None,
            };
            (t, C::Vector(comps))
        }
        _ => return None,
    })
}

#[derive(Clone, Debug, PartialEq)]
pub enum ConstValue {
    F32(f32),
    U32(u32),
    I32(i32),
    Vector(Vec<f64>),
}
