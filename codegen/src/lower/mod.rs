//! The target-independent lowering of a linked, type-checked program to shader text.
//!
//! One walk serves every language: the structure (which functions and in which order,
//! statements, control flow, evaluation order, specialisation, names, the source map) is the
//! same everywhere and only spellings differ; those come from a [`Language`]. Divergent
//! semantics go through small helper functions (`lp_*`), emitted only when used.
//!
//! - `mod.rs`: the pass structure, function order, output plumbing.
//! - `stmt.rs`: functions and statements; what becomes a statement and what an expression.
//! - `expr.rs`: expressions, casts, built-in calls and methods.
//! - `specialize.rs`: conditions and resource fields fixed at code-generation time.
//! - `assemble.rs`: the file around the functions (structs, consts, resources, helpers, entry).
//! - `harness.rs`: the equivalence-test harness layout.

mod assemble;
mod expr;
mod harness;
mod specialize;
mod stmt;

use std::collections::{BTreeMap, BTreeSet};
use std::rc::Rc;

use crate::infer::FnTypes;
use crate::ir::{self, BinOp, Expr, ExprKind as K};
use crate::language::{prec, Helpers, Language};
use crate::names;
use crate::types::{Scalar, Ty};
use crate::{CodegenError, Generated, Located, Program, Selection, SourceMapEntry, Target};

type R<T> = Result<T, CodegenError>;

pub(crate) fn emit(program: &Program, target: Target, selection: &Selection) -> R<Generated> {
    let specialized = specialize::fix_consts(program, &selection.specialize)?;
    let program = specialized.as_ref().unwrap_or(program);
    let lang = target.language();
    let order = fn_order(program, selection);
    if !lang.supports_compute() {
        refuse_compute(program, target, selection, &order)?;
    }
    // First pass: which calls survive specialisation. Second pass: only what is reached. Both
    // lower the same functions of the same program, so each function's types are inferred once.
    let mut types = BTreeMap::new();
    let first = lower_functions(program, lang, selection, &order, &mut types)?;
    let roots: Vec<String> =
        order.iter().filter(|n| selection.roots.is_empty() || selection.roots.contains(n)).cloned().collect();
    let mut reached = BTreeSet::new();
    let mut stack = roots;
    while let Some(n) = stack.pop() {
        if reached.insert(n.clone()) {
            stack.extend(first.calls.get(&n).into_iter().flatten().cloned());
        }
    }
    let order: Vec<String> = order.into_iter().filter(|n| reached.contains(n)).collect();
    let mut l = lower_functions(program, lang, selection, &order, &mut types)?;
    let (source, source_map, harness, bindings) = l.assemble(&order)?;
    Ok(Generated { target, source, source_map, harness, bindings })
}

/// A language without storage buffers and atomics (GLSL ES 3.00) refuses compute entry points
/// and every function of a `#[kernel(compute)]` module, at the function.
fn refuse_compute(program: &Program, target: Target, selection: &Selection, order: &[String]) -> R<()> {
    let target_name = match target {
        Target::GlslEs300 => "GLSL ES 3.00",
        Target::Wgsl => "WGSL",
    };
    let refused = selection
        .compute
        .iter()
        .chain(order.iter().filter(|n| program.fns.get(*n).is_some_and(|f| program.is_compute_module(&f.module))))
        .find_map(|n| program.fns.get(n));
    match refused {
        Some(f) => Err(CodegenError {
            file: f.file.clone(),
            span: f.item.span,
            function: Some(format!("{}::{}", f.module, f.item.name)),
            message: format!(
                "`{}` is a compute kernel (storage, atomics): {target_name} has neither; it is generated for WGSL and the CPU only",
                f.item.name
            ),
        }),
        None => Ok(()),
    }
}

fn lower_functions<'a>(
    program: &'a Program,
    lang: &'a dyn Language,
    selection: &'a Selection,
    order: &[String],
    types: &mut BTreeMap<String, Rc<FnTypes>>,
) -> R<Lowerer<'a>> {
    let mut l = Lowerer {
        program,
        lang,
        body: String::new(),
        body_lines: 0,
        indent: 0,
        helpers: BTreeSet::new(),
        map: Vec::new(),
        structs_used: BTreeSet::new(),
        consts_used: BTreeSet::new(),
        resources_used: BTreeSet::new(),
        func: None,
        types: Rc::default(),
        used_names: BTreeSet::new(),
        selection,
        calls: BTreeMap::new(),
    };
    for name in order {
        let f = &program.fns[name];
        l.types = match types.get(name) {
            Some(t) => Rc::clone(t),
            None => {
                let t = Rc::new(crate::infer::infer_fn(program, f)?);
                types.insert(name.clone(), Rc::clone(&t));
                t
            }
        };
        l.function(f)?;
    }
    Ok(l)
}

/// The selected functions and their callees, callees first (shading languages need
/// declaration before use). Deterministic: roots in link order, callees in call order.
fn fn_order(program: &Program, selection: &Selection) -> Vec<String> {
    let mut roots: Vec<String> = Vec::new();
    for m in &program.modules {
        for item in &m.items {
            if let ir::Item::Fn(f) = item {
                if selection.roots.is_empty() || selection.roots.contains(&f.name) {
                    roots.push(f.name.clone());
                }
            }
        }
    }
    fn visit(p: &Program, name: &str, done: &mut BTreeSet<String>, out: &mut Vec<String>) {
        if !done.insert(name.to_string()) {
            return;
        }
        for (callee, _) in p.callees(name) {
            visit(p, &callee, done, out);
        }
        out.push(name.to_string());
    }
    let mut done = BTreeSet::new();
    let mut out = Vec::new();
    for r in roots {
        visit(program, &r, &mut done, &mut out);
    }
    out
}

/// The state of one pass over the selected functions.
struct Lowerer<'a> {
    program: &'a Program,
    lang: &'a dyn Language,
    body: String,
    body_lines: u32,
    indent: usize,
    helpers: Helpers,
    map: Vec<SourceMapEntry>,
    structs_used: BTreeSet<String>,
    consts_used: BTreeSet<String>,
    /// (resource struct, field)
    resources_used: BTreeSet<(String, String)>,
    func: Option<&'a Located<ir::FnDef>>,
    /// The types of the function being lowered (set before `function` is called).
    types: Rc<FnTypes>,
    used_names: BTreeSet<String>,
    selection: &'a Selection,
    /// Kernel functions each emitted function calls (after specialisation).
    calls: BTreeMap<String, BTreeSet<String>>,
}

fn snake(name: &str) -> String {
    let mut out = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_uppercase() {
            if i > 0 {
                out.push('_');
            }
            out.extend(c.to_lowercase());
        } else {
            out.push(c);
        }
    }
    out
}

impl Program {
    /// Global names that resource fields take in generated code.
    pub(crate) fn resource_globals(&self) -> BTreeSet<String> {
        let mut out = BTreeSet::new();
        for s in self.structs.values().filter(|s| s.item.resources) {
            let base = snake(&s.item.name);
            out.insert(base.clone());
            for f in &s.item.fields {
                out.insert(format!("{base}_{}", f.name));
            }
        }
        out
    }
}

fn is_zero_literal(e: &Expr) -> bool {
    match &e.kind {
        K::Lit(ir::Lit::Int { value, .. }) => *value == 0,
        K::Lit(ir::Lit::Float { value, .. }) => *value == 0.0 && value.is_sign_positive(),
        K::Lit(ir::Lit::Bool(b)) => !*b,
        K::Paren(e) => is_zero_literal(e),
        _ => false,
    }
}

/// Whether evaluating `e` can change state (it calls a kernel function, takes `&mut`, or writes
/// storage or atomics).
fn has_effects(e: &Expr) -> bool {
    let mut effects = false;
    crate::walk_expr(e, &mut |x| {
        let writes =
            matches!(&x.kind, K::MethodCall { method, .. } if method == "store" || method.starts_with("atomic_"));
        if writes || matches!(x.kind, K::Call { .. } | K::AddrOfMut(_) | K::Assign { .. }) {
            effects = true;
        }
    });
    effects
}

fn strip_parens(e: &Expr) -> &Expr {
    match &e.kind {
        K::Paren(inner) => strip_parens(inner),
        _ => e,
    }
}

/// A float literal that reads back as the same f32 (always with a `.` or an exponent). The
/// shortest decimal of `f32::MAX` (`3.4028235e38`) is above `f32::MAX` as a real number, which
/// WGSL rejects (an abstract float outside f32's finite range: Chromium's Tint refuses it, naga
/// accepts it): such values are written as their exact value (`3.4028234663852886e38`).
pub(crate) fn float_lit(v: f32) -> String {
    let shortest = format!("{v:?}");
    let s = match shortest.parse::<f64>() {
        Ok(x) if x.is_finite() && x.abs() > f64::from(f32::MAX) => format!("{:e}", f64::from(v)),
        _ => shortest,
    };
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

fn op_prec(op: BinOp) -> u8 {
    match op {
        BinOp::Mul | BinOp::Div | BinOp::Rem => prec::MUL,
        BinOp::Add | BinOp::Sub => prec::ADD,
        BinOp::Shl | BinOp::Shr => prec::SHIFT,
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => prec::REL,
        BinOp::Eq | BinOp::Ne => prec::EQ,
        BinOp::BitAnd => prec::BAND,
        BinOp::BitXor => prec::BXOR,
        BinOp::BitOr => prec::BOR,
        BinOp::And => prec::LAND,
        BinOp::Or => prec::LOR,
    }
}

/// The suffix of a helper's name for the type it works on: `f32`, `vec3`, `uvec4`, ...
fn helper_suffix(t: &Ty) -> String {
    match t {
        Ty::Vector(s, n) => {
            let p = match s {
                Scalar::F32 => "",
                Scalar::I32 => "i",
                Scalar::U32 | Scalar::USize => "u",
                Scalar::Bool => "b",
            };
            format!("{p}vec{n}")
        }
        _ => "f32".into(),
    }
}

impl<'a> Lowerer<'a> {
    fn error(&self, span: ir::Span, msg: impl Into<String>) -> CodegenError {
        let f = self.func.expect("inside a function");
        CodegenError {
            file: f.file.clone(),
            span,
            function: Some(format!("{}::{}", f.module, f.item.name)),
            message: msg.into(),
        }
    }

    fn line(&mut self, text: &str) {
        for _ in 0..self.indent {
            self.body.push_str("    ");
        }
        self.body.push_str(text);
        self.body.push('\n');
        self.body_lines += 1;
    }

    /// Records that the next emitted line comes from `span` of the current function.
    fn mark(&mut self, span: ir::Span) {
        if let Some(f) = self.func {
            let line = self.body_lines + 1;
            if self.map.last().is_some_and(|m| m.line == line) {
                self.map.pop();
            }
            self.map.push(SourceMapEntry {
                line,
                file: f.file.clone(),
                span,
                function: format!("{}::{}", f.module, f.item.name),
            });
        }
    }

    fn fresh(&mut self, base: &str) -> String {
        let fns = &self.program.fns;
        names::unique_local(base, &mut self.used_names, |n| fns.contains_key(n))
    }

    /// Records the structs a type names, so that their declarations are emitted.
    fn note_structs(&mut self, t: &Ty) {
        match t {
            Ty::Struct(name) => {
                self.structs_used.insert(name.clone());
            }
            Ty::Array(elem, _) | Ty::RefMut(elem) => self.note_structs(elem),
            _ => {}
        }
    }

    fn ty_name(&mut self, t: &Ty) -> String {
        self.note_structs(t);
        self.lang.type_name(t)
    }

    fn decl(&mut self, t: &Ty, name: &str) -> String {
        self.note_structs(t);
        self.lang.decl(t, name)
    }

    fn local(&mut self, t: &Ty, name: &str, mutable: bool) -> String {
        self.note_structs(t);
        self.lang.local(t, name, mutable)
    }

    /// Whether the value of `e` is a struct or an array.
    fn is_composite(&self, e: &Expr) -> bool {
        matches!(self.types.ty(strip_parens(e)), Ty::Struct(_) | Ty::Array(..))
    }
}

/// A reduction helper's name (without `lp_` and the type suffix) and the expression folding
/// the components of `v` left to right, as glam does: `((x op y) op z)`.
pub(crate) fn reduce_parts(op: &str, n: u8) -> (&'static str, String) {
    let name = match op {
        "min" => "min_element",
        "max" => "max_element",
        "+" => "element_sum",
        _ => "element_product",
    };
    let comps: Vec<String> = "xyzw"[..n as usize].chars().map(|c| format!("v.{c}")).collect();
    let mut expr = comps[0].clone();
    for c in &comps[1..] {
        expr = if op.len() > 1 { format!("{op}({expr}, {c})") } else { format!("{expr} {op} {c}") };
    }
    (name, expr)
}

#[cfg(test)]
mod tests {
    use super::float_lit;

    /// Every literal reads back as its value, and as a decimal lies within f32's range (Tint
    /// refuses a literal above f32::MAX even when it would round down to it).
    #[test]
    fn float_literals_read_back_within_range() {
        for v in [f32::MAX, -f32::MAX, f32::MIN_POSITIVE, 1.0e-45, 0.1, 3.0e38, -2.5, 1.0] {
            let s = float_lit(v);
            assert_eq!(s.parse::<f32>().unwrap(), v, "{s}");
            assert!(s.parse::<f64>().unwrap().abs() <= f32::MAX as f64, "{s} exceeds f32::MAX as a decimal");
        }
    }
}
