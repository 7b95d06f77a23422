//! The syntax of a kernel module, as captured by the `#[kernel]` attribute.
//!
//! The macro checks that the module stays inside the supported Rust subset, then records
//! its items here (untyped: rustc has already type-checked the same code, and codegen
//! infers what it needs). Every node carries the line and column of its Rust source so
//! that code generation and shader validation errors point back at the kernel source.

use serde::{Deserialize, Serialize};

/// One `#[kernel] mod name { ... }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Module {
    /// The module's identifier (`rng` for `mod rng`).
    pub name: String,
    /// The source file as `<package>/<path in the package>` (`lightport-tracer/src/kernel/rng.rs`),
    /// the same on every machine; rustc's own name for it when built outside Cargo.
    pub file: String,
    /// Kernel modules this one imports with `use` (last path segment of each module path).
    pub imports: Vec<Import>,
    pub items: Vec<Item>,
    /// `#[kernel(compute)]`: the module may use `Storage` and `Atomics` resources (compute
    /// stages). Generated for WGSL and the CPU only: GLSL ES 3.00 has neither.
    #[serde(default, skip_serializing_if = "is_false")]
    pub compute: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

impl Module {
    /// Decodes the description the macro embedded in the compiled crate.
    pub fn from_json(json: &str) -> Module {
        serde_json::from_str(json).expect("kernel-dsl: the embedded IR was written by a matching macro")
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("IR serializes")
    }
}

/// A `use` inside a kernel module: either a whole kernel module (`use super::rng::*`) or
/// named items of one (`use super::rng::{random_float, wang_hash}`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Import {
    pub path: Vec<String>,
    /// `None` for a glob import.
    pub names: Option<Vec<String>>,
    pub span: Span,
}

/// A position in the kernel's Rust source (1-based line, 0-based column as rustc reports).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Span {
    pub line: u32,
    pub column: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Item {
    Struct(StructDef),
    Const(ConstDef),
    Fn(FnDef),
}

impl Item {
    pub fn name(&self) -> &str {
        match self {
            Item::Struct(s) => &s.name,
            Item::Const(c) => &c.name,
            Item::Fn(f) => &f.name,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StructDef {
    pub name: String,
    pub fields: Vec<Field>,
    /// `#[resources]`: the struct describes scene data bound to the kernel (data textures
    /// and uniforms) rather than a value type. Passed as `&Name`; it disappears in shaders.
    pub resources: bool,
    /// `#[resources(group = N)]`: the WGSL bind group of the struct's bindings (default 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub group: u32,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Field {
    pub name: String,
    pub ty: Type,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConstDef {
    pub name: String,
    pub ty: Type,
    pub value: Expr,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FnDef {
    pub name: String,
    pub params: Vec<Param>,
    pub ret: Option<Type>,
    pub body: Block,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Param {
    pub name: String,
    pub ty: Type,
    /// `mut x: T` (a mutable by-value parameter).
    pub mutable: bool,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Type {
    /// `f32`, `Vec3`, a struct name, or a generic such as `Texels<Vec4>`.
    Named { name: String, args: Vec<Type> },
    /// `[T; N]`
    Array { elem: Box<Type>, len: ArrayLen },
    /// `&T` or `&mut T`
    Ref { mutable: bool, inner: Box<Type> },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ArrayLen {
    Literal(u32),
    Const(String),
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Block {
    pub stmts: Vec<Stmt>,
    /// The block's value: its final expression without a semicolon.
    pub tail: Option<Box<Expr>>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Stmt {
    Let {
        name: String,
        mutable: bool,
        ty: Option<Type>,
        init: Option<Expr>,
        span: Span,
    },
    /// An expression statement (with or without a trailing semicolon in the source).
    Expr(Expr),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    And,
    Or,
    BitAnd,
    BitOr,
    BitXor,
    Shl,
    Shr,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
}

impl BinOp {
    pub fn is_comparison(self) -> bool {
        matches!(self, BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge)
    }
    pub fn is_logical(self) -> bool {
        matches!(self, BinOp::And | BinOp::Or)
    }
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Rem => "%",
            BinOp::And => "&&",
            BinOp::Or => "||",
            BinOp::BitAnd => "&",
            BinOp::BitOr => "|",
            BinOp::BitXor => "^",
            BinOp::Shl => "<<",
            BinOp::Shr => ">>",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum UnOp {
    Neg,
    Not,
    Deref,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Lit {
    /// The literal's digits as written (underscores removed), and its suffix if any.
    Int {
        digits: String,
        value: u64,
        suffix: Option<String>,
    },
    Float {
        value: f32,
        suffix: Option<String>,
    },
    Bool(bool),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MatchArm {
    /// Integer patterns joined by `|`; empty means `_`.
    pub patterns: Vec<Expr>,
    pub body: Expr,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ExprKind {
    Lit(Lit),
    /// A variable, const or associated item: `x`, `PI`, `Vec3::ZERO`, `f32::consts::PI`.
    Path(Vec<String>),
    Unary {
        op: UnOp,
        expr: Box<Expr>,
    },
    Binary {
        op: BinOp,
        lhs: Box<Expr>,
        rhs: Box<Expr>,
    },
    /// `place = value` or `place op= value`.
    Assign {
        op: Option<BinOp>,
        place: Box<Expr>,
        value: Box<Expr>,
    },
    /// A call through a path: `foo(a)`, `Vec3::new(x, y, z)`, `f32::max(a, b)`.
    Call {
        path: Vec<String>,
        args: Vec<Expr>,
    },
    MethodCall {
        receiver: Box<Expr>,
        method: String,
        args: Vec<Expr>,
    },
    Field {
        base: Box<Expr>,
        field: String,
    },
    Index {
        base: Box<Expr>,
        index: Box<Expr>,
    },
    Cast {
        expr: Box<Expr>,
        ty: Type,
    },
    StructLit {
        name: String,
        fields: Vec<(String, Expr)>,
    },
    Array(Vec<Expr>),
    ArrayRepeat {
        value: Box<Expr>,
        len: ArrayLen,
    },
    /// `&mut place`
    AddrOfMut(Box<Expr>),
    /// `&place` (only of a resource struct, to pass it on)
    AddrOf(Box<Expr>),
    If {
        cond: Box<Expr>,
        then: Block,
        otherwise: Option<Box<Expr>>,
    },
    Match {
        scrutinee: Box<Expr>,
        arms: Vec<MatchArm>,
    },
    Block(Block),
    While {
        cond: Box<Expr>,
        body: Block,
    },
    Loop {
        body: Block,
    },
    ForRange {
        var: String,
        start: Box<Expr>,
        end: Box<Expr>,
        inclusive: bool,
        body: Block,
    },
    Break,
    Continue,
    Return(Option<Box<Expr>>),
    Paren(Box<Expr>),
}

/// Names of the methods (and `Type::method(receiver, ..)` calls) the subset supports.
/// The macro refuses any other method at its span; codegen implements each of these for
/// the receiver types where rustc accepts them (a codegen test checks the two agree).
pub const SUPPORTED_METHODS: &[&str] = &[
    // f32
    "sqrt",
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "atan2",
    "exp",
    "exp2",
    "ln",
    "log2",
    "powf",
    "floor",
    "ceil",
    "round",
    "trunc",
    "fract",
    "abs",
    "min",
    "max",
    "clamp",
    "signum",
    "recip",
    "to_bits",
    "is_nan",
    "is_finite",
    "is_infinite",
    "to_radians",
    "to_degrees",
    // u32 / i32
    "wrapping_add",
    "wrapping_sub",
    "wrapping_mul",
    "wrapping_neg",
    "wrapping_shl",
    "wrapping_shr",
    // glam vectors
    "dot",
    "cross",
    "length",
    "length_squared",
    "normalize",
    "distance",
    "lerp",
    "min_element",
    "max_element",
    "element_sum",
    "element_product",
    "extend",
    "truncate",
    "reflect",
    "xy",
    "xz",
    "yz",
    "xyz",
    "as_vec2",
    "as_vec3",
    "as_vec4",
    "as_uvec2",
    "as_uvec3",
    "as_uvec4",
    "as_ivec2",
    "as_ivec3",
    "as_ivec4",
    // resources
    "fetch",
    // compute resources (`#[kernel(compute)]` modules only): Storage and Atomics
    "load",
    "store",
    "atomic_add",
    "atomic_sub",
    "atomic_min",
    "atomic_max",
    "atomic_exchange",
    "atomic_load",
    "atomic_store",
];

/// The methods of `Storage` and `Atomics` (in [`SUPPORTED_METHODS`]): only a
/// `#[kernel(compute)]` module may call them.
pub const COMPUTE_METHODS: &[&str] = &[
    "load",
    "store",
    "atomic_add",
    "atomic_sub",
    "atomic_min",
    "atomic_max",
    "atomic_exchange",
    "atomic_load",
    "atomic_store",
];

/// The resource types only a `#[kernel(compute)]` module may declare (in [`BUILTIN_TYPES`]).
pub const COMPUTE_TYPES: &[&str] = &["Storage", "Atomics"];

/// Associated functions called through a type path that are not methods: constructors and
/// conversions.
pub const SUPPORTED_CONSTRUCTORS: &[&str] = &["new", "splat", "from_bits"];

/// Scalar and vector types the subset knows (besides structs declared in kernel modules).
pub const BUILTIN_TYPES: &[&str] = &[
    "f32", "i32", "u32", "bool", "usize", "Vec2", "Vec3", "Vec4", "IVec2", "IVec3", "IVec4", "UVec2", "UVec3", "UVec4",
    "Texels", "Storage", "Atomics",
];
