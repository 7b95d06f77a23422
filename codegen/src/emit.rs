//! Emission of GLSL ES 3.00 and WGSL from a linked, type-checked program.
//!
//! One emitter serves both targets: the structure (statements, control flow, evaluation
//! order) is the same and only spellings differ, so each construct is written once with a
//! `match self.target` where the languages part ways. Divergent semantics go through small
//! helper functions (`lp_*`), emitted only when used.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

use crate::infer::{self, BindingKind, FnTypes};
use crate::ir::{self, BinOp, Expr, ExprKind as K, UnOp};
use crate::names;
use crate::types::{self, ConstValue, Scalar, Ty, F32, I32, U32};
use crate::{CodegenError, Generated, Located, Program, Selection, SourceMapEntry, Target};

// Operator precedence, shared by both targets (C-like; WGSL's stricter grammar is handled
// by the rules in `binary`).
const P_TERNARY: u8 = 3;
const P_LOR: u8 = 4;
const P_LAND: u8 = 5;
const P_BOR: u8 = 6;
const P_BXOR: u8 = 7;
const P_BAND: u8 = 8;
const P_EQ: u8 = 9;
const P_REL: u8 = 10;
const P_SHIFT: u8 = 11;
const P_ADD: u8 = 12;
const P_MUL: u8 = 13;
const P_UNARY: u8 = 14;
const P_ATOM: u8 = 16;

type R<T> = Result<T, CodegenError>;

/// Where the value of a block-like expression (`if`, `match`, block) goes.
#[derive(Clone)]
enum Dest {
    Return,
    Assign(String),
    Discard,
}

pub(crate) fn emit(program: &Program, target: Target, selection: &Selection) -> R<Generated> {
    let order = fn_order(program, selection);
    // First pass: which calls survive specialisation. Second pass: only what is reached.
    let first = emit_functions(program, target, selection, &order)?;
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
    let mut e = emit_functions(program, target, selection, &order)?;
    e.assemble(&order)
}

fn emit_functions<'a>(
    program: &'a Program,
    target: Target,
    selection: &'a Selection,
    order: &[String],
) -> R<Emitter<'a>> {
    let mut e = Emitter {
        program,
        target,
        body: String::new(),
        body_lines: 0,
        indent: 0,
        helpers: BTreeSet::new(),
        map: Vec::new(),
        structs_used: BTreeSet::new(),
        consts_used: BTreeSet::new(),
        resources_used: BTreeSet::new(),
        func: None,
        types: FnTypes::default(),
        used_names: BTreeSet::new(),
        selection,
        calls: BTreeMap::new(),
    };
    for name in order {
        e.function(&program.fns[name])?;
    }
    Ok(e)
}

/// The selected functions and their callees, callees first (GLSL needs declaration before
/// use). Deterministic: roots in link order, callees in call order.
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

/// Divergence helpers, in the order they are emitted (dependencies first).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Helper {
    U32ToF32,
    I32ToF32,
    F32ToU32,
    F32ToI32,
    DivI32,
    RemI32,
    FmodF32,
    IsNan,
    IsInfinite,
    IsFinite,
    Signum,
    Round,
    /// `x - trunc(x)` for the given GLSL type name.
    Fract(String),
    LengthSquared(String),
    Reduce {
        op: &'static str,
        ty: String,
        n: u8,
    },
    FetchVec4,
    FetchUVec4,
}

struct Emitter<'a> {
    program: &'a Program,
    target: Target,
    body: String,
    body_lines: u32,
    indent: usize,
    helpers: BTreeSet<Helper>,
    map: Vec<SourceMapEntry>,
    structs_used: BTreeSet<String>,
    consts_used: BTreeSet<String>,
    /// (resource struct, field)
    resources_used: BTreeSet<(String, String)>,
    func: Option<&'a Located<ir::FnDef>>,
    types: FnTypes,
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
    pub(crate) fn resource_globals(&self) -> Vec<String> {
        let mut out = Vec::new();
        for s in self.structs.values().filter(|s| s.item.resources) {
            let base = snake(&s.item.name);
            out.push(base.clone());
            for f in &s.item.fields {
                out.push(format!("{base}_{}", f.name));
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

/// Whether evaluating `e` can change state (it calls a kernel function or takes `&mut`).
fn has_effects(e: &Expr) -> bool {
    let mut effects = false;
    crate::walk_expr(e, &mut |x| {
        if matches!(x.kind, K::Call { .. } | K::AddrOfMut(_) | K::Assign { .. }) {
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

fn wrap(s: (String, u8), min: u8) -> String {
    if s.1 < min {
        format!("({})", s.0)
    } else {
        s.0
    }
}

fn float_lit(v: f32) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

impl<'a> Emitter<'a> {
    fn error(&self, span: ir::Span, msg: impl Into<String>) -> CodegenError {
        let f = self.func.expect("inside a function");
        CodegenError {
            file: f.file.clone(),
            span,
            function: Some(format!("{}::{}", f.module, f.item.name)),
            message: msg.into(),
        }
    }

    fn glsl(&self) -> bool {
        self.target == Target::GlslEs300
    }

    // ---------------------------------------------------------------- output plumbing

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
        names::unique_local(base, &mut self.used_names)
    }

    // ---------------------------------------------------------------- types

    fn ty_name(&mut self, t: &Ty) -> String {
        let glsl = self.glsl();
        match t {
            Ty::Scalar(s) => scalar_name(*s, glsl).to_string(),
            Ty::IntVar(_) => scalar_name(Scalar::I32, glsl).to_string(),
            Ty::Vector(s, n) => vector_name(*s, *n, glsl),
            Ty::Struct(name) => {
                self.structs_used.insert(name.clone());
                names::safe(name)
            }
            Ty::Array(elem, n) => {
                let e = self.ty_name(elem);
                if glsl {
                    format!("{e}[{n}]")
                } else {
                    format!("array<{e}, {n}>")
                }
            }
            Ty::RefMut(inner) => self.ty_name(inner),
            Ty::Unit | Ty::Never => "void".into(),
            Ty::Texels(_) | Ty::Resource(_) => "<resource>".into(),
        }
    }

    /// `T name` in GLSL (arrays: `T name[N]`), `name: T` in WGSL.
    fn decl(&mut self, t: &Ty, name: &str) -> String {
        if self.glsl() {
            match t {
                Ty::Array(elem, n) => {
                    let e = self.ty_name(elem);
                    format!("{e} {name}[{n}]")
                }
                _ => format!("{} {name}", self.ty_name(t)),
            }
        } else {
            format!("{name}: {}", self.ty_name(t))
        }
    }

    // ---------------------------------------------------------------- functions

    fn function(&mut self, f: &'a Located<ir::FnDef>) -> R<()> {
        self.func = Some(f);
        self.types = infer::infer_fn(self.program, f)?;
        self.used_names = self.types.bindings.iter().map(|b| b.out_name.clone()).collect();
        self.used_names.extend(self.program.fns.keys().cloned());
        let def = &f.item;
        self.line(&format!("// {}::{} ({}:{})", f.module, def.name, f.file, def.span.line));
        let mut params = Vec::new();
        let mut prologue = Vec::new();
        for (i, p) in def.params.iter().enumerate() {
            let b = self.types.bindings[self.types.params[i]].clone();
            match b.kind {
                BindingKind::Resource => {}
                BindingKind::RefParam => {
                    let t = b.ty.strip_ref().clone();
                    if self.glsl() {
                        let d = self.decl(&t, &b.out_name);
                        params.push(format!("inout {d}"));
                    } else {
                        let tn = self.ty_name(&t);
                        params.push(format!("{}: ptr<function, {tn}>", b.out_name));
                    }
                }
                _ => {
                    if !self.glsl() && (p.mutable || matches!(b.ty, Ty::Array(..))) {
                        // WGSL parameters are immutable (and arrays are only indexable
                        // dynamically in a `var`): copy into a variable of the Rust name.
                        let arg = self.fresh(&format!("{}_arg", p.name));
                        let tn = self.ty_name(&b.ty);
                        params.push(format!("{arg}: {tn}"));
                        prologue.push(format!("var {}: {tn} = {arg};", b.out_name));
                    } else {
                        params.push(self.decl(&b.ty, &b.out_name));
                    }
                }
            }
        }
        let ret = self.types.ret.clone();
        let name = names::safe(&def.name);
        let header = if self.glsl() {
            let r = self.ty_name(&ret);
            format!("{r} {name}({}) {{", params.join(", "))
        } else if ret == Ty::Unit {
            format!("fn {name}({}) {{", params.join(", "))
        } else {
            let r = self.ty_name(&ret);
            format!("fn {name}({}) -> {r} {{", params.join(", "))
        };
        self.mark(def.span);
        self.line(&header);
        self.indent += 1;
        for p in prologue {
            self.line(&p);
        }
        let dest = if ret == Ty::Unit { Dest::Discard } else { Dest::Return };
        self.block_into(&def.body, &dest)?;
        self.indent -= 1;
        self.line("}");
        self.line("");
        self.func = None;
        Ok(())
    }

    // ---------------------------------------------------------------- statements

    fn block_stmts(&mut self, b: &ir::Block) -> R<()> {
        for s in &b.stmts {
            self.stmt(s)?;
        }
        Ok(())
    }

    /// Emits a block's statements, then its tail into `dest`.
    fn block_into(&mut self, b: &ir::Block, dest: &Dest) -> R<()> {
        self.block_stmts(b)?;
        if let Some(t) = &b.tail {
            self.value_into(t, dest)?;
        }
        Ok(())
    }

    /// Block-like values become statements (`T x; if (c) { x = a; } else { x = b; }`), except an
    /// `if` whose branches are single pure expressions: that stays a `?:` / `select`.
    fn is_block_like(&self, e: &Expr) -> bool {
        let e = strip_parens(e);
        match &e.kind {
            K::If { .. } => !self.is_simple_if(e),
            K::Match { .. } | K::Block(_) => true,
            _ => false,
        }
    }

    /// An `if` that can be a `?:` / `select`: pure single-expression branches, and a scalar or
    /// vector value. WGSL's `select` takes nothing else; GLSL ES 3.00 drivers differ on `?:`
    /// over structs (Mesa takes it, ANGLE in Chromium fails the page's shader).
    fn is_simple_if(&self, e: &Expr) -> bool {
        let K::If { then, otherwise: Some(o), .. } = &strip_parens(e).kind else {
            return false;
        };
        if self.is_composite(e) {
            return false;
        }
        let Some(t) = then.tail.as_deref().filter(|_| then.stmts.is_empty()) else {
            return false;
        };
        let o = strip_parens(o);
        let o_tail = match &o.kind {
            K::Block(b) if b.stmts.is_empty() => b.tail.as_deref(),
            K::If { .. } => Some(o),
            _ => None,
        };
        let simple_branch =
            |x: &Expr| !has_effects(x) && (!matches!(strip_parens(x).kind, K::If { .. }) || self.is_simple_if(x));
        matches!(o_tail, Some(ot) if simple_branch(t) && simple_branch(ot))
    }

    /// Whether the value of `e` is a struct or an array.
    fn is_composite(&self, e: &Expr) -> bool {
        matches!(self.types.ty(strip_parens(e)), Ty::Struct(_) | Ty::Array(..))
    }

    fn value_into(&mut self, e: &Expr, dest: &Dest) -> R<()> {
        let e = strip_parens(e);
        match &e.kind {
            K::If { cond, then, otherwise } if self.const_bool(cond).is_some() => {
                // Decided by specialisation: emit only the live branch.
                if self.const_bool(cond) == Some(true) {
                    self.block_into(then, dest)?;
                } else if let Some(o) = otherwise {
                    self.value_into(o, dest)?;
                }
            }
            K::If { cond, then, otherwise } if !self.is_simple_if(e) => {
                self.mark(e.span);
                let c = self.expr(cond)?;
                if self.glsl() {
                    self.line(&format!("if ({}) {{", c.0));
                } else {
                    self.line(&format!("if {} {{", c.0));
                }
                self.indent += 1;
                self.block_into(then, dest)?;
                self.indent -= 1;
                let mut otherwise = otherwise.as_deref().map(strip_parens);
                // `else if` chains stay flat; an `else` block is emitted without extra braces.
                while let Some(o) = otherwise {
                    match &o.kind {
                        // Branches decided by specialisation: skip a dead `else if`, or end
                        // the chain at a live one.
                        K::If { cond, otherwise: next, .. } if self.const_bool(cond) == Some(false) => {
                            otherwise = next.as_deref().map(strip_parens);
                        }
                        K::If { cond, then, .. } if self.const_bool(cond) == Some(true) => {
                            self.line("} else {");
                            self.indent += 1;
                            self.block_into(then, dest)?;
                            self.indent -= 1;
                            otherwise = None;
                        }
                        K::If { cond, then, otherwise: next } => {
                            let c = self.expr(cond)?.0;
                            self.line(&if self.glsl() {
                                format!("}} else if ({c}) {{")
                            } else {
                                format!("}} else if {c} {{")
                            });
                            self.indent += 1;
                            self.block_into(then, dest)?;
                            self.indent -= 1;
                            otherwise = next.as_deref().map(strip_parens);
                        }
                        K::Block(b) => {
                            self.line("} else {");
                            self.indent += 1;
                            self.block_into(b, dest)?;
                            self.indent -= 1;
                            otherwise = None;
                        }
                        _ => {
                            self.line("} else {");
                            self.indent += 1;
                            self.value_into(o, dest)?;
                            self.indent -= 1;
                            otherwise = None;
                        }
                    }
                }
                self.line("}");
            }
            K::Block(b) => {
                self.line("{");
                self.indent += 1;
                self.block_into(b, dest)?;
                self.indent -= 1;
                self.line("}");
            }
            K::Match { scrutinee, arms } => self.match_into(e, scrutinee, arms, dest)?,
            K::While { .. }
            | K::Loop { .. }
            | K::ForRange { .. }
            | K::Return(_)
            | K::Break
            | K::Continue
            | K::Assign { .. } => self.stmt_expr(e)?,
            _ => {
                let ty = self.types.ty(e).clone();
                self.mark(e.span);
                let v = self.expr(e)?.0;
                match dest {
                    Dest::Return => self.line(&format!("return {v};")),
                    Dest::Assign(place) => self.line(&format!("{place} = {v};")),
                    Dest::Discard if ty == Ty::Unit || self.glsl() || matches!(e.kind, K::Call { .. }) => {
                        self.line(&format!("{v};"))
                    }
                    Dest::Discard => self.line(&format!("_ = {v};")),
                }
            }
        }
        Ok(())
    }

    fn match_into(&mut self, e: &Expr, scrutinee: &Expr, arms: &[ir::MatchArm], dest: &Dest) -> R<()> {
        self.mark(e.span);
        let s_ty = self.types.ty(scrutinee).clone();
        let s = match &strip_parens(scrutinee).kind {
            K::Path(_) | K::Lit(_) => self.expr(scrutinee)?.0,
            _ => {
                let name = self.fresh("match_value");
                let v = self.expr(scrutinee)?.0;
                let d = self.decl(&s_ty, &name);
                let kw = if self.glsl() { "" } else { "let " };
                self.line(&format!("{kw}{d} = {v};"));
                name
            }
        };
        let mut first = true;
        let mut closed = false;
        for arm in arms {
            if arm.patterns.is_empty() {
                // `_`: everything left.
                if first {
                    self.line("{");
                } else {
                    self.line("} else {");
                }
                self.indent += 1;
                self.value_into(&arm.body, dest)?;
                self.indent -= 1;
                self.line("}");
                closed = true;
                break;
            }
            let mut conds = Vec::new();
            for p in &arm.patterns {
                let pv = self.expr(p)?.0;
                conds.push(format!("{s} == {pv}"));
            }
            let c = conds.join(" || ");
            let head = match (first, self.glsl()) {
                (true, true) => format!("if ({c}) {{"),
                (true, false) => format!("if {c} {{"),
                (false, true) => format!("}} else if ({c}) {{"),
                (false, false) => format!("}} else if {c} {{"),
            };
            self.line(&head);
            self.indent += 1;
            self.value_into(&arm.body, dest)?;
            self.indent -= 1;
            first = false;
        }
        if !closed && !first {
            self.line("}");
        }
        Ok(())
    }

    fn stmt(&mut self, s: &ir::Stmt) -> R<()> {
        match s {
            ir::Stmt::Let { init, span, .. } => {
                let id = self.types.lets[&infer::stmt_key(s)];
                let b = self.types.bindings[id].clone();
                self.mark(*span);
                let needs_var =
                    b.mutable || matches!(b.ty, Ty::Array(..)) || init.as_ref().is_none_or(|i| self.is_block_like(i));
                let kw = match (self.glsl(), needs_var) {
                    (true, _) => "",
                    (false, true) => "var ",
                    (false, false) => "let ",
                };
                let d = self.decl(&b.ty, &b.out_name);
                match init {
                    None => self.line(&format!("{kw}{d};")),
                    Some(init) if self.is_block_like(init) => {
                        self.line(&format!("{kw}{d};"));
                        self.value_into(init, &Dest::Assign(b.out_name.clone()))?;
                    }
                    Some(init) => {
                        if let K::ArrayRepeat { value, .. } = &strip_parens(init).kind {
                            let Ty::Array(_, n) = b.ty else { unreachable!("array type") };
                            self.line(&format!("{kw}{d};"));
                            // WGSL zero-initialises; GLSL leaves locals undefined.
                            if !is_zero_literal(value) || self.glsl() {
                                let v = self.expr(value)?.0;
                                let i = self.fresh("i");
                                if self.glsl() {
                                    self.line(&format!(
                                        "for (int {i} = 0; {i} < {n}; ++{i}) {{ {}[{i}] = {v}; }}",
                                        b.out_name
                                    ));
                                } else {
                                    self.line(&format!(
                                        "for (var {i}: u32 = 0u; {i} < {n}u; {i}++) {{ {}[{i}] = {v}; }}",
                                        b.out_name
                                    ));
                                }
                            }
                        } else {
                            let v = self.expr(init)?.0;
                            self.line(&format!("{kw}{d} = {v};"));
                        }
                    }
                }
                Ok(())
            }
            ir::Stmt::Expr(e) => self.stmt_expr(e),
        }
    }

    fn stmt_expr(&mut self, e: &Expr) -> R<()> {
        let e = strip_parens(e);
        let glsl = self.glsl();
        match &e.kind {
            K::If { .. } | K::Match { .. } | K::Block(_) => self.value_into(e, &Dest::Discard),
            K::While { cond, body } => {
                self.mark(e.span);
                let c = self.expr(cond)?.0;
                self.line(&if glsl { format!("while ({c}) {{") } else { format!("while {c} {{") });
                self.indent += 1;
                self.block_into(body, &Dest::Discard)?;
                self.indent -= 1;
                self.line("}");
                Ok(())
            }
            K::Loop { body } => {
                self.mark(e.span);
                self.line(if glsl { "while (true) {" } else { "loop {" });
                self.indent += 1;
                self.block_into(body, &Dest::Discard)?;
                self.indent -= 1;
                self.line("}");
                Ok(())
            }
            K::ForRange { start, end, inclusive, body, .. } => {
                self.mark(e.span);
                let id = self.types.for_vars[&infer::key(e)];
                let b = self.types.bindings[id].clone();
                let tn = self.ty_name(&b.ty);
                let s = self.expr(start)?.0;
                // Rust evaluates the end once; keep that when it could change.
                let end_is_fixed = match &strip_parens(end).kind {
                    K::Lit(_) => true,
                    K::Path(p) => {
                        self.types.uses.get(&infer::key(strip_parens(end))).is_none_or(|id| {
                            let bind = &self.types.bindings[*id];
                            !bind.mutable && bind.kind != BindingKind::RefParam
                        }) || p.len() > 1
                    }
                    _ => false,
                };
                let en = if end_is_fixed {
                    self.expr(end)?.0
                } else {
                    let name = self.fresh(&format!("{}_end", b.out_name));
                    let v = self.expr(end)?.0;
                    let kw = if glsl { format!("{tn} {name}") } else { format!("let {name}: {tn}") };
                    self.line(&format!("{kw} = {v};"));
                    name
                };
                let cmp = if *inclusive { "<=" } else { "<" };
                let v = &b.out_name;
                self.line(&if glsl {
                    format!("for ({tn} {v} = {s}; {v} {cmp} {en}; ++{v}) {{")
                } else {
                    format!("for (var {v}: {tn} = {s}; {v} {cmp} {en}; {v}++) {{")
                });
                self.indent += 1;
                self.block_into(body, &Dest::Discard)?;
                self.indent -= 1;
                self.line("}");
                Ok(())
            }
            K::Break => {
                self.mark(e.span);
                self.line("break;");
                Ok(())
            }
            K::Continue => {
                self.mark(e.span);
                self.line("continue;");
                Ok(())
            }
            K::Return(v) => match v {
                None => {
                    self.mark(e.span);
                    self.line("return;");
                    Ok(())
                }
                Some(v) => self.value_into(v, &Dest::Return),
            },
            K::Assign { op, place, value } => {
                self.mark(e.span);
                let p = self.place(place)?;
                if self.is_block_like(value) {
                    if let Some(op) = op {
                        let t = self.types.ty(value).clone();
                        let tmp = self.fresh("value");
                        let d = self.decl(&t, &tmp);
                        self.line(&if glsl { format!("{d};") } else { format!("var {d};") });
                        self.value_into(value, &Dest::Assign(tmp.clone()))?;
                        let pt = self.types.ty(place).strip_ref().clone();
                        let rhs = self.binary_text(*op, (p.clone(), P_ATOM), &pt, (tmp, P_ATOM), &t, e.span)?;
                        self.line(&format!("{p} = {};", rhs.0));
                        return Ok(());
                    }
                    return self.value_into(value, &Dest::Assign(p));
                }
                let v = self.expr(value)?;
                match op {
                    None => self.line(&format!("{p} = {};", v.0)),
                    Some(op) => {
                        let pt = self.types.ty(place).strip_ref().clone();
                        let vt = self.types.ty(value).clone();
                        let rhs = self.binary_text(*op, (p.clone(), P_ATOM), &pt, v.clone(), &vt, e.span)?;
                        // Keep `x op= v` where the target operator means the same thing.
                        let plain = format!("{p} {} ", op.symbol());
                        match rhs.0.strip_prefix(&plain) {
                            Some(_) => {
                                let v = self.shift_amount(*op, v, &vt);
                                self.line(&format!("{p} {}= {};", op.symbol(), v.0));
                            }
                            None => self.line(&format!("{p} = {};", rhs.0)),
                        }
                    }
                }
                Ok(())
            }
            _ => self.value_into(e, &Dest::Discard),
        }
    }

    // ---------------------------------------------------------------- expressions

    /// An assignable place: a variable, `*param`, a field or an element.
    fn place(&mut self, e: &Expr) -> R<String> {
        Ok(self.expr(e)?.0)
    }

    fn expr(&mut self, e: &Expr) -> R<(String, u8)> {
        let glsl = self.glsl();
        let span = e.span;
        Ok(match &e.kind {
            K::Lit(l) => (self.literal(l, self.types.ty(e).clone()), P_ATOM),
            K::Paren(inner) => self.expr(inner)?,
            K::Path(path) => self.path(e, path)?,
            K::Unary { op, expr } => {
                let inner = self.expr(expr)?;
                let t = self.types.ty(expr).clone();
                match op {
                    UnOp::Deref => {
                        if glsl {
                            inner
                        } else {
                            (format!("*{}", wrap(inner, P_ATOM)), P_UNARY)
                        }
                    }
                    UnOp::Neg => (format!("-{}", wrap(inner, P_ATOM)), P_UNARY),
                    UnOp::Not if t.scalar() == Some(Scalar::Bool) => (format!("!{}", wrap(inner, P_ATOM)), P_UNARY),
                    UnOp::Not => (format!("~{}", wrap(inner, P_ATOM)), P_UNARY),
                }
            }
            K::Binary { op, lhs, rhs } => {
                let l = self.expr(lhs)?;
                let r = self.expr(rhs)?;
                let lt = self.types.ty(lhs).clone();
                let rt = self.types.ty(rhs).clone();
                self.binary_text(*op, l, &lt, r, &rt, span)?
            }
            K::Assign { .. } => return Err(self.error(span, "assignments are statements in kernels")),
            K::Call { path, args } => self.call(e, path, args)?,
            K::MethodCall { receiver, method, args } => self.method(e, receiver, method, args)?,
            K::Field { base, field } => {
                let bt = self.types.ty(base).clone();
                if let Ty::Resource(res) = bt.strip_ref() {
                    return Ok(self.resource_field(res, field));
                }
                let b = self.expr(base)?;
                let b = self.auto_deref(b, &bt);
                (format!("{}.{}", wrap(b, P_ATOM), names::safe(field)), P_ATOM)
            }
            K::Index { base, index } => {
                let bt = self.types.ty(base).clone();
                let b = self.expr(base)?;
                let b = self.auto_deref(b, &bt);
                let i = self.expr(index)?;
                (format!("{}[{}]", wrap(b, P_ATOM), i.0), P_ATOM)
            }
            K::Cast { expr, .. } => {
                let from = self.types.ty(expr).clone();
                let to = self.types.ty(e).clone();
                self.cast(expr, &from, &to)?
            }
            K::StructLit { name, fields } => {
                let def = self.program.structs[name].item.clone();
                let in_order = def.fields.iter().map(|f| &f.name).eq(fields.iter().map(|(n, _)| n));
                if !in_order && fields.iter().filter(|(_, v)| has_effects(v)).count() > 0 {
                    return Err(self.error(
                        span,
                        format!("write the fields of `{name}` in declaration order: they have side effects, and shader constructors take fields in declaration order"),
                    ));
                }
                let mut vals = Vec::new();
                for f in &def.fields {
                    let Some((_, v)) = fields.iter().find(|(n, _)| *n == f.name) else {
                        return Err(self.error(span, format!("missing field `{}`", f.name)));
                    };
                    vals.push(self.expr(v)?.0);
                }
                self.structs_used.insert(name.clone());
                (format!("{}({})", names::safe(name), vals.join(", ")), P_ATOM)
            }
            K::Array(elems) => {
                let t = self.types.ty(e).clone();
                let tn = self.ty_name(&t);
                let mut vals = Vec::new();
                for el in elems {
                    vals.push(self.expr(el)?.0);
                }
                (format!("{tn}({})", vals.join(", ")), P_ATOM)
            }
            K::ArrayRepeat { value, .. } => {
                // In an expression: an array constructor repeating a simple value.
                let t = self.types.ty(e).clone();
                let Ty::Array(_, n) = t else { unreachable!("array type") };
                let simple = matches!(strip_parens(value).kind, K::Lit(_) | K::Path(_));
                if !simple || n > 32 {
                    return Err(self.error(
                        span,
                        "`[value; N]` inside an expression needs a literal or const value and N <= 32: bind it with `let` instead",
                    ));
                }
                let tn = self.ty_name(&t);
                if !glsl && is_zero_literal(value) {
                    (format!("{tn}()"), P_ATOM)
                } else {
                    let v = self.expr(value)?.0;
                    (format!("{tn}({})", vec![v; n as usize].join(", ")), P_ATOM)
                }
            }
            K::AddrOfMut(place) => {
                let pt = self.types.ty(place).clone();
                let p = self.expr(place)?;
                if let Ty::RefMut(_) = pt {
                    // `&mut *param` or passing a `&mut` parameter on.
                    return Ok(p);
                }
                if glsl {
                    p
                } else {
                    (format!("&{}", wrap(p, P_ATOM)), P_UNARY)
                }
            }
            K::AddrOf(inner) => self.expr(inner)?,
            K::If { cond, then, otherwise } if self.const_bool(cond).is_some() => {
                match (self.const_bool(cond), then.tail.as_deref(), otherwise.as_deref()) {
                    (Some(true), Some(t), _) if then.stmts.is_empty() => self.expr(t)?,
                    (Some(false), _, Some(o)) => self.expr(o)?,
                    _ => return Err(self.error(span, "bind this `if` to a `let` first")),
                }
            }
            K::If { cond, then, otherwise } => {
                let (Some(t), Some(o)) = (then.tail.as_ref(), otherwise.as_ref()) else {
                    return Err(self.error(span, "an `if` without `else` has no value"));
                };
                let o = strip_parens(o);
                let o_tail = match &o.kind {
                    K::Block(b) if b.stmts.is_empty() => b.tail.as_deref(),
                    K::If { .. } => Some(o),
                    _ => None,
                };
                let Some(o_tail) = o_tail.filter(|_| then.stmts.is_empty()) else {
                    return Err(self.error(
                        span,
                        "bind this `if` to a `let` first: in this position its branches must be single expressions",
                    ));
                };
                if has_effects(t) || has_effects(o_tail) {
                    return Err(self.error(span, "bind this `if` to a `let` first: its branches have side effects"));
                }
                if self.is_composite(e) {
                    return Err(self.error(
                        span,
                        "bind this `if` to a `let` first: its value is a struct or an array, which `select` (WGSL) and `?:` (GLSL ES) cannot choose portably",
                    ));
                }
                let c = self.expr(cond)?;
                let a = self.expr(t)?;
                let b = self.expr(o_tail)?;
                if glsl {
                    (
                        format!("{} ? {} : {}", wrap(c, P_TERNARY + 1), wrap(a, P_TERNARY + 1), wrap(b, P_TERNARY)),
                        P_TERNARY,
                    )
                } else {
                    (format!("select({}, {}, {})", b.0, a.0, c.0), P_ATOM)
                }
            }
            K::Block(b) if b.stmts.is_empty() && b.tail.is_some() => self.expr(b.tail.as_ref().expect("tail"))?,
            K::Match { .. } | K::Block(_) => {
                return Err(self
                    .error(span, "bind this expression to a `let` first: block-like values are statements in shaders"))
            }
            K::While { .. } | K::Loop { .. } | K::ForRange { .. } | K::Break | K::Continue | K::Return(_) => {
                return Err(self.error(span, "control flow is not supported inside an expression: make it a statement"))
            }
        })
    }

    /// The value of a condition fixed by specialisation (`res.flag != 0 && ...`), if any.
    fn const_bool(&self, e: &Expr) -> Option<bool> {
        if self.selection.specialize.is_empty() {
            return None;
        }
        let e = strip_parens(e);
        match &e.kind {
            K::Lit(ir::Lit::Bool(b)) => Some(*b),
            K::Unary { op: UnOp::Not, expr } => self.const_bool(expr).map(|b| !b),
            K::Binary { op: BinOp::And, lhs, rhs } => match (self.const_bool(lhs), self.const_bool(rhs)) {
                (Some(false), _) | (_, Some(false)) => Some(false),
                (Some(true), Some(true)) => Some(true),
                _ => None,
            },
            K::Binary { op: BinOp::Or, lhs, rhs } => match (self.const_bool(lhs), self.const_bool(rhs)) {
                (Some(true), _) | (_, Some(true)) => Some(true),
                (Some(false), Some(false)) => Some(false),
                _ => None,
            },
            K::Binary { op, lhs, rhs } if op.is_comparison() => {
                let (a, b) = (self.const_u64(lhs)?, self.const_u64(rhs)?);
                Some(match op {
                    BinOp::Eq => a == b,
                    BinOp::Ne => a != b,
                    BinOp::Lt => a < b,
                    BinOp::Le => a <= b,
                    BinOp::Gt => a > b,
                    _ => a >= b,
                })
            }
            _ => None,
        }
    }

    fn const_u64(&self, e: &Expr) -> Option<u64> {
        match &strip_parens(e).kind {
            K::Lit(ir::Lit::Int { value, .. }) => Some(*value),
            K::Field { base, field } => match self.types.ty(base).strip_ref() {
                Ty::Resource(res) => self.specialized(res, field).map(u64::from),
                _ => None,
            },
            _ => None,
        }
    }

    /// Rust dereferences `&mut` automatically for fields, indexing and methods; WGSL does not.
    fn auto_deref(&self, v: (String, u8), t: &Ty) -> (String, u8) {
        if matches!(t, Ty::RefMut(_)) && !self.glsl() {
            (format!("(*{})", v.0), P_ATOM)
        } else {
            v
        }
    }

    fn specialized(&self, res: &str, field: &str) -> Option<u32> {
        self.selection.specialize.get(&format!("{res}.{field}")).copied()
    }

    fn resource_field(&mut self, res: &str, field: &str) -> (String, u8) {
        if let Some(v) = self.specialized(res, field) {
            return (format!("{v}u"), P_ATOM);
        }
        self.resources_used.insert((res.to_string(), field.to_string()));
        let def = &self.program.structs[res].item;
        let is_texels = def
            .fields
            .iter()
            .any(|f| f.name == field && matches!(&f.ty, ir::Type::Named { name, .. } if name == "Texels"));
        let base = snake(res);
        if self.glsl() || is_texels {
            (format!("{base}_{field}"), P_ATOM)
        } else {
            (format!("{base}.{}", names::safe(field)), P_ATOM)
        }
    }

    fn literal(&mut self, l: &ir::Lit, ty: Ty) -> String {
        let glsl = self.glsl();
        match l {
            ir::Lit::Bool(b) => b.to_string(),
            ir::Lit::Float { value, .. } => float_lit(*value),
            ir::Lit::Int { digits, value, .. } => {
                if ty == F32 {
                    return float_lit(*value as f32);
                }
                let digits = if digits.starts_with("0b") || digits.starts_with("0o") {
                    format!("{value:#x}")
                } else {
                    digits.clone()
                };
                match ty {
                    Ty::Scalar(Scalar::U32 | Scalar::USize) => format!("{digits}u"),
                    _ if glsl => digits,
                    _ => format!("{digits}i"),
                }
            }
        }
    }

    fn const_value(&mut self, t: &Ty, v: &ConstValue) -> String {
        match v {
            ConstValue::F32(f) if f.is_nan() => self.bits_to_float(0x7fc0_0000),
            ConstValue::F32(f) if *f == f32::INFINITY => self.bits_to_float(0x7f80_0000),
            ConstValue::F32(f) if *f == f32::NEG_INFINITY => self.bits_to_float(0xff80_0000),
            ConstValue::F32(f) => float_lit(*f),
            ConstValue::U32(u) => format!("{u}u"),
            ConstValue::I32(i) if *i == i32::MIN => "(-2147483647 - 1)".into(),
            ConstValue::I32(i) if self.glsl() => i.to_string(),
            ConstValue::I32(i) => format!("{i}i"),
            ConstValue::Vector(comps) => {
                let tn = self.ty_name(t);
                let s = t.scalar().unwrap_or(Scalar::F32);
                let all_same = comps.windows(2).all(|w| w[0] == w[1]);
                let comp = |c: f64| match s {
                    Scalar::F32 => float_lit(c as f32),
                    Scalar::U32 => format!("{}u", c as u32),
                    _ if self.glsl() => format!("{}", c as i32),
                    _ => format!("{}i", c as i32),
                };
                if all_same {
                    format!("{tn}({})", comp(comps[0]))
                } else {
                    format!("{tn}({})", comps.iter().map(|c| comp(*c)).collect::<Vec<_>>().join(", "))
                }
            }
        }
    }

    /// NaN and infinities have no literal in GLSL, and WGSL rejects them in constant
    /// expressions: build them from bits.
    fn bits_to_float(&self, bits: u32) -> String {
        if self.glsl() {
            format!("uintBitsToFloat({bits:#010x}u)")
        } else {
            format!("bitcast<f32>({bits:#010x}u)")
        }
    }

    fn path(&mut self, e: &Expr, path: &[String]) -> R<(String, u8)> {
        if let Some(id) = self.types.uses.get(&infer::key(e)) {
            let b = &self.types.bindings[*id];
            return Ok((b.out_name.clone(), P_ATOM));
        }
        let name = path.last().expect("non-empty path");
        if (path.len() == 1 || types::assoc_const(path).is_none()) && self.program.consts.contains_key(name) {
            self.consts_used.insert(name.clone());
            return Ok((names::safe(name), P_ATOM));
        }
        match types::assoc_const(path) {
            Some((t, v)) => {
                let s = self.const_value(&t, &v);
                let p = if s.starts_with('-') || s.starts_with('(') { P_UNARY } else { P_ATOM };
                Ok((s, p))
            }
            None => Err(self.error(e.span, format!("`{}` is not supported in kernels", path.join("::")))),
        }
    }

    fn binary_text(
        &mut self,
        op: BinOp,
        l: (String, u8),
        lt: &Ty,
        r: (String, u8),
        rt: &Ty,
        span: ir::Span,
    ) -> R<(String, u8)> {
        let glsl = self.glsl();
        let p = op_prec(op);
        let lt = lt.strip_ref();
        let is_vec = matches!(lt, Ty::Vector(..));
        // Semantics that differ between targets.
        match op {
            BinOp::Div if *lt == I32 && glsl => {
                self.helpers.insert(Helper::DivI32);
                return Ok((format!("lp_div_i32({}, {})", l.0, r.0), P_ATOM));
            }
            BinOp::Rem if *lt == I32 && glsl => {
                self.helpers.insert(Helper::DivI32);
                self.helpers.insert(Helper::RemI32);
                return Ok((format!("lp_rem_i32({}, {})", l.0, r.0), P_ATOM));
            }
            BinOp::Rem if lt.scalar() == Some(Scalar::F32) && glsl => {
                if is_vec || matches!(rt, Ty::Vector(..)) {
                    return Err(self.error(span, "`%` on float vectors is not supported: apply it per component"));
                }
                self.helpers.insert(Helper::FmodF32);
                return Ok((format!("lp_fmod_f32({}, {})", l.0, r.0), P_ATOM));
            }
            BinOp::Eq | BinOp::Ne if is_vec && !glsl => {
                let f = if op == BinOp::Eq { "all" } else { "any" };
                return Ok((format!("{f}({} {} {})", l.0, op.symbol(), r.0), P_ATOM));
            }
            _ => {}
        }
        let (lmin, rmin) = match op {
            // WGSL: bitwise operands are unary expressions (same-operator chains excepted);
            // shifts take unary operands on both sides.
            BinOp::BitAnd | BinOp::BitOr | BinOp::BitXor => (if l.1 == p { p } else { P_UNARY }, P_UNARY),
            BinOp::Shl | BinOp::Shr => (P_UNARY, P_UNARY),
            BinOp::And | BinOp::Or => (if l.1 == p { p } else { P_REL }, P_REL),
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => (P_SHIFT, P_SHIFT),
            _ => (p, p + 1),
        };
        let r = self.shift_amount(op, r, rt);
        Ok((format!("{} {} {}", wrap(l, lmin), op.symbol(), wrap(r, rmin)), p))
    }

    /// WGSL shift amounts are u32; the DSL only allows literal amounts for `<<`/`>>`.
    fn shift_amount(&self, op: BinOp, r: (String, u8), rt: &Ty) -> (String, u8) {
        match op {
            BinOp::Shl | BinOp::Shr if !self.glsl() && rt.strip_ref() != &U32 => {
                let digits = r.0.trim_end_matches('i');
                (format!("{digits}u"), P_ATOM)
            }
            _ => r,
        }
    }

    fn cast(&mut self, inner: &Expr, from: &Ty, to: &Ty) -> R<(String, u8)> {
        use Scalar::*;
        let glsl = self.glsl();
        let (Some(f), Some(t)) = (from.scalar(), to.scalar()) else {
            return Err(self.error(inner.span, "unsupported cast"));
        };
        let v = self.expr(inner)?;
        let same = |a: Scalar| if a == USize { U32 } else { a };
        let conv = |name: &str| (format!("{name}({})", v.0), P_ATOM);
        Ok(match (same(f), same(t)) {
            (a, b) if a == b => v,
            (F32, U32) => {
                self.helpers.insert(Helper::F32ToU32);
                conv("lp_f32_to_u32")
            }
            (F32, I32) => {
                self.helpers.insert(Helper::F32ToI32);
                conv("lp_f32_to_i32")
            }
            (I32, U32) => conv(if glsl { "uint" } else { "bitcast<u32>" }),
            (U32, I32) => conv(if glsl { "int" } else { "bitcast<i32>" }),
            (U32, F32) => {
                if fits_in_24_bits(inner) {
                    // Exact in f32: the plain conversion cannot round.
                    conv(if glsl { "float" } else { "f32" })
                } else {
                    self.helpers.insert(Helper::U32ToF32);
                    conv("lp_u32_to_f32")
                }
            }
            (I32, F32) => {
                self.helpers.insert(Helper::U32ToF32);
                self.helpers.insert(Helper::I32ToF32);
                conv("lp_i32_to_f32")
            }
            (Bool, I32) => conv(if glsl { "int" } else { "i32" }),
            (Bool, U32) => conv(if glsl { "uint" } else { "u32" }),
            (a, b) => {
                return Err(self.error(
                    inner.span,
                    format!("cast from {} to {} is not supported", types::scalar_rust(a), types::scalar_rust(b)),
                ))
            }
        })
    }

    fn call(&mut self, e: &Expr, path: &[String], args: &[Expr]) -> R<(String, u8)> {
        let glsl = self.glsl();
        if let Some(name) = self.program.kernel_fn_of_path(path) {
            if let Some(f) = self.func {
                self.calls.entry(f.item.name.clone()).or_default().insert(name.to_string());
            }
            let callee = &self.program.fns[name].item;
            let mut out = Vec::new();
            for (p, a) in callee.params.iter().zip(args) {
                let resource = matches!(&p.ty, ir::Type::Ref { mutable: false, .. });
                if resource {
                    continue;
                }
                out.push(self.expr(a)?.0);
            }
            return Ok((format!("{}({})", names::safe(name), out.join(", ")), P_ATOM));
        }
        let ty_name = path[0].as_str();
        let f = path[1].as_str();
        let t = self.types.ty(e).clone();
        match f {
            "new" | "splat" => {
                let tn = self.ty_name(&t);
                let mut vals = Vec::new();
                for a in args {
                    vals.push(self.expr(a)?.0);
                }
                Ok((format!("{tn}({})", vals.join(", ")), P_ATOM))
            }
            "from_bits" if ty_name == "f32" => {
                let v = self.expr(&args[0])?.0;
                Ok((if glsl { format!("uintBitsToFloat({v})") } else { format!("bitcast<f32>({v})") }, P_ATOM))
            }
            _ => self.method(e, &args[0], f, &args[1..]),
        }
    }

    fn method(&mut self, e: &Expr, receiver: &Expr, method: &str, args: &[Expr]) -> R<(String, u8)> {
        let glsl = self.glsl();
        let rt = self.types.ty(receiver).strip_ref().clone();
        if method == "fetch" {
            let K::Field { base, field } = &strip_parens(receiver).kind else {
                return Err(self.error(e.span, "read texels as `resources.field.fetch(index)`"));
            };
            let Ty::Resource(res) = self.types.ty(base).strip_ref().clone() else {
                return Err(self.error(e.span, "read texels as `resources.field.fetch(index)`"));
            };
            let tex = self.resource_field(&res, field).0;
            let i = self.expr(&args[0])?.0;
            if glsl {
                let (h, name) = match rt {
                    Ty::Texels(el) if matches!(*el, Ty::Vector(Scalar::U32, _)) => {
                        (Helper::FetchUVec4, "lp_fetch_uvec4")
                    }
                    _ => (Helper::FetchVec4, "lp_fetch_vec4"),
                };
                self.helpers.insert(h);
                return Ok((format!("{name}({tex}, {i})"), P_ATOM));
            }
            return Ok((format!("{tex}[{i}]"), P_ATOM));
        }
        let recv = self.expr(receiver)?;
        let recv_t = self.types.ty(receiver).clone();
        let r = self.auto_deref(recv, &recv_t);
        let mut a = Vec::new();
        for x in args {
            a.push(self.expr(x)?);
        }
        let tn = self.ty_name(&rt);
        let call = |f: &str, r: &(String, u8), a: &[(String, u8)]| {
            let mut all = vec![r.0.clone()];
            all.extend(a.iter().map(|x| x.0.clone()));
            (format!("{f}({})", all.join(", ")), P_ATOM)
        };
        let int = rt.is_int();
        Ok(match method {
            "sqrt" | "sin" | "cos" | "tan" | "asin" | "acos" | "atan" | "exp" | "exp2" | "log2" | "floor" | "ceil"
            | "trunc" | "abs" | "min" | "max" | "clamp" | "dot" | "cross" | "length" | "normalize" | "reflect" => {
                call(method, &r, &a)
            }
            "ln" => call("log", &r, &a),
            "powf" => call("pow", &r, &a),
            "lerp" => call("mix", &r, &a),
            "atan2" => call(if glsl { "atan" } else { "atan2" }, &r, &a),
            "recip" => (format!("1.0 / {}", wrap(r, P_MUL + 1)), P_MUL),
            "to_radians" => (format!("{} * {}", wrap(r, P_MUL), float_lit(std::f32::consts::PI / 180.0)), P_MUL),
            "to_degrees" => (format!("{} * {}", wrap(r, P_MUL), float_lit(180.0 / std::f32::consts::PI)), P_MUL),
            "fract" => {
                self.helpers.insert(Helper::Fract(tn.clone()));
                call(&format!("lp_fract_{}", helper_suffix(&tn)), &r, &a)
            }
            "round" => {
                self.helpers.insert(Helper::Round);
                call("lp_round", &r, &a)
            }
            "signum" => {
                self.helpers.insert(Helper::IsNan);
                self.helpers.insert(Helper::Signum);
                call("lp_signum", &r, &a)
            }
            "to_bits" => call(if glsl { "floatBitsToUint" } else { "bitcast<u32>" }, &r, &a),
            "is_nan" => {
                self.helpers.insert(Helper::IsNan);
                call("lp_is_nan", &r, &a)
            }
            "is_infinite" => {
                self.helpers.insert(Helper::IsInfinite);
                call("lp_is_infinite", &r, &a)
            }
            "is_finite" => {
                self.helpers.insert(Helper::IsFinite);
                call("lp_is_finite", &r, &a)
            }
            "wrapping_add" if int => (format!("{} + {}", wrap(r, P_ADD), wrap(a[0].clone(), P_ADD + 1)), P_ADD),
            "wrapping_sub" if int => (format!("{} - {}", wrap(r, P_ADD), wrap(a[0].clone(), P_ADD + 1)), P_ADD),
            "wrapping_mul" if int => (format!("{} * {}", wrap(r, P_MUL), wrap(a[0].clone(), P_MUL + 1)), P_MUL),
            "wrapping_neg" if rt == U32 => (format!("0u - {}", wrap(r, P_ADD + 1)), P_ADD),
            "wrapping_neg" => (format!("-{}", wrap(r, P_ATOM)), P_UNARY),
            "wrapping_shl" | "wrapping_shr" => {
                let op = if method == "wrapping_shl" { "<<" } else { ">>" };
                (format!("{} {op} ({} & 31u)", wrap(r, P_UNARY), wrap(a[0].clone(), P_UNARY)), P_SHIFT)
            }
            "length_squared" => {
                self.helpers.insert(Helper::LengthSquared(tn.clone()));
                call(&format!("lp_length_squared_{}", helper_suffix(&tn)), &r, &a)
            }
            "distance" => (format!("length({} - {})", r.0, wrap(a[0].clone(), P_ADD + 1)), P_ATOM),
            "min_element" | "max_element" | "element_sum" | "element_product" => {
                let (op, f) = match method {
                    "min_element" => ("min", "min_element"),
                    "max_element" => ("max", "max_element"),
                    "element_sum" => ("+", "element_sum"),
                    _ => ("*", "element_product"),
                };
                let Ty::Vector(_, n) = rt else { unreachable!("vector receiver") };
                self.helpers.insert(Helper::Reduce { op, ty: tn.clone(), n });
                call(&format!("lp_{f}_{}", helper_suffix(&tn)), &r, &a)
            }
            "extend" => {
                let t = self.types.ty(e).clone();
                let ext = self.ty_name(&t);
                (format!("{ext}({}, {})", r.0, a[0].0), P_ATOM)
            }
            "truncate" => {
                let Ty::Vector(_, n) = rt else { unreachable!("vector receiver") };
                (format!("{}.{}", wrap(r, P_ATOM), &"xyzw"[..n as usize - 1]), P_ATOM)
            }
            "xy" | "xz" | "yz" | "xyz" => (format!("{}.{method}", wrap(r, P_ATOM)), P_ATOM),
            m if m.starts_with("as_") => {
                let t = self.types.ty(e).clone();
                let target = self.ty_name(&t);
                (format!("{target}({})", r.0), P_ATOM)
            }
            other => return Err(self.error(e.span, format!("`{other}` is not implemented for `{rt}` in codegen"))),
        })
    }

    // ---------------------------------------------------------------- assembly

    fn assemble(&mut self, order: &[String]) -> R<Generated> {
        let glsl = self.glsl();
        let mut out = String::new();
        let modules: Vec<String> = {
            let mut seen = Vec::new();
            for n in order {
                let m = &self.program.fns[n].module;
                if !seen.contains(m) {
                    seen.push(m.clone());
                }
            }
            seen
        };
        if glsl {
            out.push_str("#version 300 es\n");
        }
        let _ = writeln!(
            out,
            "// Generated by lightport-codegen from the kernel DSL (modules: {}). Do not edit: regenerate with `cargo run -- shaders`.",
            modules.join(", ")
        );
        if glsl {
            out.push_str("precision highp float;\nprecision highp int;\nprecision highp sampler2D;\nprecision highp usampler2D;\n");
        }
        out.push('\n');

        // Resources used.
        let resources_used = self.resources_used.clone();
        let mut binding = 0;
        let res_structs: Vec<String> = self
            .program
            .modules
            .iter()
            .flat_map(|m| m.items.iter())
            .filter_map(|i| match i {
                ir::Item::Struct(s) if s.resources => Some(s.name.clone()),
                _ => None,
            })
            .collect();
        for res in &res_structs {
            let def = self.program.structs[res].item.clone();
            let used: Vec<&ir::Field> =
                def.fields.iter().filter(|f| resources_used.contains(&(res.clone(), f.name.clone()))).collect();
            if used.is_empty() {
                continue;
            }
            let base = snake(res);
            let _ = writeln!(out, "// resources: {} ({}:{})", res, self.program.structs[res].file, def.span.line);
            let mut uniforms = Vec::new();
            for f in &used {
                let t = infer::resolve_type(self.program, &f.ty).map_err(|m| CodegenError {
                    file: self.program.structs[res].file.clone(),
                    span: f.span,
                    function: None,
                    message: m,
                })?;
                match &t {
                    Ty::Texels(el) => {
                        let unsigned = matches!(**el, Ty::Vector(Scalar::U32, _));
                        if glsl {
                            let s = if unsigned { "usampler2D" } else { "sampler2D" };
                            let _ = writeln!(out, "uniform highp {s} {base}_{};", f.name);
                        } else {
                            let e = if unsigned { "vec4<u32>" } else { "vec4<f32>" };
                            // Bindings after the uniform block (binding 0) of this struct.
                            uniforms.push((f.name.clone(), None, Some(e)));
                        }
                    }
                    Ty::Scalar(Scalar::Bool) | Ty::Vector(Scalar::Bool, _) => {
                        return Err(CodegenError {
                            file: self.program.structs[res].file.clone(),
                            span: f.span,
                            function: None,
                            message: "resource fields cannot be `bool` (not host-shareable in WGSL): use `u32`".into(),
                        })
                    }
                    Ty::Scalar(_) | Ty::Vector(..) => {
                        let tn = self.ty_name(&t);
                        if glsl {
                            let _ = writeln!(out, "uniform {tn} {base}_{};", f.name);
                        } else {
                            uniforms.push((f.name.clone(), Some(tn), None));
                        }
                    }
                    other => {
                        return Err(CodegenError {
                            file: self.program.structs[res].file.clone(),
                            span: f.span,
                            function: None,
                            message: format!(
                                "resource fields are `Texels<..>` or scalars/vectors (uniforms), not `{other}`"
                            ),
                        })
                    }
                }
            }
            if !glsl {
                let scalars: Vec<_> = uniforms.iter().filter(|u| u.1.is_some()).collect();
                if !scalars.is_empty() {
                    let _ = writeln!(out, "struct {res}Uniforms {{");
                    for (name, tn, _) in &scalars {
                        let _ = writeln!(out, "    {}: {},", names::safe(name), tn.as_deref().unwrap_or_default());
                    }
                    out.push_str("}\n");
                    let _ = writeln!(out, "@group(0) @binding({binding}) var<uniform> {base}: {res}Uniforms;");
                    binding += 1;
                }
                for (name, _, el) in uniforms.iter().filter(|u| u.2.is_some()) {
                    let _ = writeln!(
                        out,
                        "@group(0) @binding({binding}) var<storage, read> {base}_{name}: array<{}>;",
                        el.unwrap_or_default()
                    );
                    binding += 1;
                }
            }
            out.push('\n');
        }

        // Structs (dependencies first) and consts.
        let structs = self.struct_order();
        for s in structs {
            let located = &self.program.structs[&s];
            let def = located.item.clone();
            let _ = writeln!(out, "// {}::{} ({}:{})", located.module, def.name, located.file, def.span.line);
            let _ = writeln!(out, "struct {} {{", names::safe(&def.name));
            for f in &def.fields {
                let t = infer::resolve_type(self.program, &f.ty).map_err(|m| CodegenError {
                    file: located.file.clone(),
                    span: f.span,
                    function: None,
                    message: m,
                })?;
                if glsl {
                    let d = self.decl(&t, &names::safe(&f.name));
                    let _ = writeln!(out, "    {d};");
                } else {
                    let d = self.decl(&t, &names::safe(&f.name));
                    let _ = writeln!(out, "    {d},");
                }
            }
            out.push_str(if glsl { "};\n\n" } else { "}\n\n" });
        }
        let consts: Vec<String> = self
            .program
            .modules
            .iter()
            .flat_map(|m| m.items.iter())
            .filter_map(|i| match i {
                ir::Item::Const(c) if self.consts_used.contains(&c.name) => Some(c.name.clone()),
                _ => None,
            })
            .collect();
        for c in consts {
            let located = self.program.consts[&c].clone();
            let t = infer::resolve_type(self.program, &located.item.ty).map_err(|m| CodegenError {
                file: located.file.clone(),
                span: located.item.span,
                function: None,
                message: m,
            })?;
            let v = self.const_expr(&located, &t)?;
            let d = self.decl(&t, &names::safe(&c));
            let _ = writeln!(out, "// {}::{} ({}:{})", located.module, c, located.file, located.item.span.line);
            let _ = writeln!(out, "const {d} = {v};");
        }
        if !self.consts_used.is_empty() {
            out.push('\n');
        }

        // Helpers.
        let helpers: Vec<Helper> = self.helpers.iter().cloned().collect();
        if !helpers.is_empty() {
            out.push_str("// Helpers that keep the DSL's (Rust's) semantics where the shading languages differ.\n");
        }
        for h in helpers {
            out.push_str(&helper_text(&h, glsl));
            out.push('\n');
        }

        let offset = out.lines().count() as u32;
        out.push_str(&self.body);
        if let Some(entry) = &self.selection.entry {
            out.push_str(&self.entry_point(entry)?);
        }
        let mut harness = None;
        if let Some(function) = &self.selection.harness {
            let (text, layout) = self.harness(function)?;
            out.push_str(&text);
            harness = Some(layout);
        }
        while out.ends_with("\n\n") {
            out.pop();
        }
        let source_map = self.map.iter().map(|m| SourceMapEntry { line: m.line + offset, ..m.clone() }).collect();
        Ok(Generated { target: self.target, source: out, source_map, harness })
    }

    fn entry_point(&mut self, entry: &crate::EntryPoint) -> R<String> {
        let f = self.program.fns.get(&entry.function).ok_or_else(|| CodegenError {
            file: String::new(),
            span: ir::Span::default(),
            function: None,
            message: format!("entry point `{}` is not a kernel function", entry.function),
        })?;
        let types = infer::infer_fn(self.program, f)?;
        let params: Vec<&Ty> =
            types.params.iter().map(|i| &types.bindings[*i].ty).filter(|t| !matches!(t, Ty::Resource(_))).collect();
        if params != [&U32, &U32] || types.ret != Ty::Vector(Scalar::F32, 4) {
            return Err(CodegenError {
                file: f.file.clone(),
                span: f.item.span,
                function: Some(format!("{}::{}", f.module, f.item.name)),
                message: "an entry point takes (resources, x: u32, y: u32) and returns Vec4".into(),
            });
        }
        let name = names::safe(&entry.function);
        Ok(if self.glsl() {
            format!(
                "// Entry point: one sample of pixel gl_FragCoord.xy added to the running sum.\nuniform highp sampler2D lp_accumulation;\nout vec4 lp_out;\n\nvoid main() {{\n    uvec2 pixel = uvec2(gl_FragCoord.xy);\n    lp_out = texelFetch(lp_accumulation, ivec2(pixel), 0) + {name}(pixel.x, pixel.y);\n}}\n"
            )
        } else {
            format!(
                "// Entry point: one sample per pixel added to the running sum in lp_accumulation.\nstruct LpTarget {{\n    width: u32,\n    height: u32,\n}}\n@group(1) @binding(0) var<storage, read_write> lp_accumulation: array<vec4<f32>>;\n@group(1) @binding(1) var<uniform> lp_target: LpTarget;\n\n@compute @workgroup_size(8, 8)\nfn main(@builtin(global_invocation_id) id: vec3<u32>) {{\n    if id.x >= lp_target.width || id.y >= lp_target.height {{\n        return;\n    }}\n    let i = id.y * lp_target.width + id.x;\n    lp_accumulation[i] = lp_accumulation[i] + {name}(id.x, id.y);\n}}\n"
            )
        })
    }

    fn harness_error(&self, message: impl Into<String>) -> CodegenError {
        CodegenError { file: String::new(), span: ir::Span::default(), function: None, message: message.into() }
    }

    /// An expression decoding a `t` from the words starting at `*next`; each word's Rust path
    /// (`origin.x`, `ray.dir.z`) and scalar type is appended to `layout`.
    fn decode(&mut self, t: &Ty, path: &str, next: &mut u32, layout: &mut Vec<crate::HarnessWord>) -> R<String> {
        let glsl = self.glsl();
        let word = |k: u32| if glsl { format!("lp_word(base, {k}u)") } else { format!("lp_args[base + {k}u]") };
        Ok(match t {
            Ty::Scalar(s) => {
                let w = word(*next);
                *next += 1;
                layout.push(crate::HarnessWord { path: path.to_string(), scalar: *s });
                match (s, glsl) {
                    (Scalar::F32, true) => format!("uintBitsToFloat({w})"),
                    (Scalar::F32, false) => format!("bitcast<f32>({w})"),
                    (Scalar::I32, true) => format!("int({w})"),
                    (Scalar::I32, false) => format!("bitcast<i32>({w})"),
                    (Scalar::Bool, _) => format!("({w} != 0u)"),
                    _ => w,
                }
            }
            Ty::Vector(s, n) => {
                let comps: Vec<String> = "xyzw"
                    .chars()
                    .take(*n as usize)
                    .map(|c| self.decode(&Ty::Scalar(*s), &format!("{path}.{c}"), next, layout))
                    .collect::<R<_>>()?;
                format!("{}({})", self.ty_name(t), comps.join(", "))
            }
            Ty::Array(e, n) => {
                let items: Vec<String> =
                    (0..*n).map(|i| self.decode(e, &format!("{path}[{i}]"), next, layout)).collect::<R<_>>()?;
                format!("{}({})", self.ty_name(t), items.join(", "))
            }
            Ty::Struct(name) => {
                let def = self.program.structs[name].item.clone();
                let mut fields = Vec::new();
                for f in &def.fields {
                    let ft = infer::resolve_type(self.program, &f.ty).map_err(|m| self.harness_error(m))?;
                    fields.push(self.decode(&ft, &format!("{path}.{}", f.name), next, layout)?);
                }
                format!("{}({})", self.ty_name(t), fields.join(", "))
            }
            other => return Err(self.harness_error(format!("`{other}` cannot cross the harness"))),
        })
    }

    /// Statements storing `value` (of type `t`) as words from `*next` into `lp_w`; each word's
    /// Rust path and scalar type is appended to `layout`.
    fn encode(
        &mut self,
        t: &Ty,
        value: &str,
        path: &str,
        next: &mut u32,
        lines: &mut Vec<String>,
        layout: &mut Vec<crate::HarnessWord>,
    ) -> R<()> {
        let glsl = self.glsl();
        match t {
            Ty::Scalar(s) => {
                let w = match (s, glsl) {
                    (Scalar::F32, true) => format!("floatBitsToUint({value})"),
                    (Scalar::F32, false) => format!("bitcast<u32>({value})"),
                    (Scalar::I32, true) | (Scalar::Bool, true) => format!("uint({value})"),
                    (Scalar::I32, false) => format!("bitcast<u32>({value})"),
                    (Scalar::Bool, false) => format!("select(0u, 1u, {value})"),
                    _ => value.to_string(),
                };
                lines.push(format!("lp_w[{}] = {w};", *next));
                layout.push(crate::HarnessWord { path: path.to_string(), scalar: *s });
                *next += 1;
            }
            Ty::Vector(s, n) => {
                for c in "xyzw".chars().take(*n as usize) {
                    self.encode(&Ty::Scalar(*s), &format!("{value}.{c}"), &format!("{path}.{c}"), next, lines, layout)?;
                }
            }
            Ty::Array(e, n) => {
                for i in 0..*n {
                    self.encode(e, &format!("{value}[{i}]"), &format!("{path}[{i}]"), next, lines, layout)?;
                }
            }
            Ty::Struct(name) => {
                let def = self.program.structs[name].item.clone();
                for f in &def.fields {
                    let ft = infer::resolve_type(self.program, &f.ty).map_err(|m| self.harness_error(m))?;
                    let (v, p) = (format!("{value}.{}", names::safe(&f.name)), format!("{path}.{}", f.name));
                    self.encode(&ft, &v, &p, next, lines, layout)?;
                }
            }
            Ty::Unit => {}
            other => return Err(self.harness_error(format!("`{other}` cannot cross the harness"))),
        }
        Ok(())
    }

    fn harness(&mut self, function: &str) -> R<(String, crate::Harness)> {
        let f = self
            .program
            .fns
            .get(function)
            .ok_or_else(|| self.harness_error(format!("`{function}` is not a kernel function")))?;
        let types = infer::infer_fn(self.program, f)?;
        let param_names: Vec<String> = f.item.params.iter().map(|p| p.name.clone()).collect();
        let glsl = self.glsl();
        let mut next = 0u32;
        let mut setup = Vec::new();
        let mut args = Vec::new();
        let mut outs = Vec::new();
        let mut inputs = Vec::new();
        let mut outputs = Vec::new();
        for (i, id) in types.params.iter().enumerate() {
            let b = &types.bindings[*id];
            let param = param_names.get(i).cloned().unwrap_or_else(|| format!("arg{i}"));
            match &b.ty {
                Ty::Resource(_) => {}
                Ty::RefMut(inner) => {
                    let name = format!("lp_arg{i}");
                    let v = self.decode(inner, &param, &mut next, &mut inputs)?;
                    let tn = self.ty_name(inner);
                    setup.push(if glsl { format!("{tn} {name} = {v};") } else { format!("var {name}: {tn} = {v};") });
                    args.push(if glsl { name.clone() } else { format!("&{name}") });
                    outs.push(((**inner).clone(), name, param));
                }
                t => {
                    let name = format!("lp_arg{i}");
                    let v = self.decode(t, &param, &mut next, &mut inputs)?;
                    let tn = self.ty_name(t);
                    setup.push(if glsl { format!("{tn} {name} = {v};") } else { format!("let {name}: {tn} = {v};") });
                    args.push(name);
                }
            }
        }
        let input_words = next;
        let call = format!("{}({})", names::safe(function), args.join(", "));
        let mut body = Vec::new();
        let mut out_next = 0u32;
        if types.ret != Ty::Unit {
            let tn = self.ty_name(&types.ret);
            body.push(if glsl {
                format!("{tn} lp_result = {call};")
            } else {
                format!("let lp_result: {tn} = {call};")
            });
            let ret = types.ret.clone();
            self.encode(&ret, "lp_result", "return", &mut out_next, &mut body, &mut outputs)?;
        } else {
            body.push(format!("{call};"));
        }
        for (t, name, param) in &outs {
            self.encode(t, name, param, &mut out_next, &mut body, &mut outputs)?;
        }
        let layout =
            crate::Harness { function: function.to_string(), input_words, output_words: out_next, inputs, outputs };
        let words = out_next.max(1);
        let mut text = String::new();
        let _ = writeln!(
            text,
            "// Equivalence-test harness around {function}: {input_words} input words, {out_next} output words."
        );
        if glsl {
            let texels = layout.input_texels();
            let attachments = layout.output_attachments();
            text.push_str(
                "uniform highp usampler2D lp_args;
",
            );
            for j in 0..attachments {
                let _ = writeln!(text, "layout(location = {j}) out uvec4 lp_out{j};");
            }
            text.push_str(
                "
uint lp_word(ivec2 base, uint k) {
    uvec4 t = texelFetch(lp_args, ivec2(base.x + int(k / 4u), base.y), 0);
    return t[int(k % 4u)];
}

void main() {
",
            );
            let _ = writeln!(
                text,
                "    ivec2 cell = ivec2(gl_FragCoord.xy);
    ivec2 base = ivec2(cell.x * {texels}, cell.y);"
            );
            for l in &setup {
                let _ = writeln!(text, "    {l}");
            }
            let _ = writeln!(text, "    uint lp_w[{}];", attachments * 4);
            let _ = writeln!(text, "    for (int i = 0; i < {}; ++i) {{ lp_w[i] = 0u; }}", attachments * 4);
            for l in &body {
                let _ = writeln!(text, "    {l}");
            }
            for j in 0..attachments {
                let k = j * 4;
                let _ = writeln!(
                    text,
                    "    lp_out{j} = uvec4(lp_w[{k}], lp_w[{}], lp_w[{}], lp_w[{}]);",
                    k + 1,
                    k + 2,
                    k + 3
                );
            }
            text.push_str(
                "}
",
            );
        } else {
            text.push_str(
                "struct LpCount {
    n: u32,
}
@group(1) @binding(0) var<storage, read> lp_args: array<u32>;
@group(1) @binding(1) var<storage, read_write> lp_results: array<u32>;
@group(1) @binding(2) var<uniform> lp_count: LpCount;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= lp_count.n {
        return;
    }
",
            );
            let _ = writeln!(text, "    let base: u32 = id.x * {}u;", input_words.max(1));
            for l in &setup {
                let _ = writeln!(text, "    {l}");
            }
            let _ = writeln!(text, "    var lp_w: array<u32, {words}>;");
            for l in &body {
                let _ = writeln!(text, "    {l}");
            }
            let _ = writeln!(
                text,
                "    for (var k: u32 = 0u; k < {words}u; k++) {{
        lp_results[id.x * {words}u + k] = lp_w[k];
    }}"
            );
            text.push_str(
                "}
",
            );
        }
        Ok((text, layout))
    }

    /// A const's value: literals, or simple expressions of literals and other consts.
    fn const_expr(&mut self, c: &Located<ir::ConstDef>, t: &Ty) -> R<String> {
        // Type the value as a tiny function would: reuse the literal/path emitters.
        fn lower(e: &mut Emitter, x: &Expr, t: &Ty, c: &Located<ir::ConstDef>) -> R<(String, u8)> {
            let err =
                |m: &str| CodegenError { file: c.file.clone(), span: x.span, function: None, message: m.to_string() };
            Ok(match &x.kind {
                K::Lit(l) => (e.literal(l, t.clone()), P_ATOM),
                K::Paren(i) => lower(e, i, t, c)?,
                K::Unary { op: UnOp::Neg, expr } => (format!("-{}", wrap(lower(e, expr, t, c)?, P_ATOM)), P_UNARY),
                K::Binary { op, lhs, rhs } if !op.is_comparison() && !op.is_logical() => {
                    let l = lower(e, lhs, t, c)?;
                    let r = lower(e, rhs, t, c)?;
                    let p = op_prec(*op);
                    (format!("{} {} {}", wrap(l, p), op.symbol(), wrap(r, p + 1)), p)
                }
                K::Path(p) => {
                    if let Some((ct, v)) = types::assoc_const(p) {
                        (e.const_value(&ct, &v), P_UNARY)
                    } else if p.len() == 1 && e.program.consts.contains_key(&p[0]) {
                        e.consts_used.insert(p[0].clone());
                        (names::safe(&p[0]), P_ATOM)
                    } else {
                        return Err(err("unknown name in const"));
                    }
                }
                K::Call { path, args } if path.len() == 2 && matches!(path[1].as_str(), "new" | "splat") => {
                    let Ty::Vector(s, _) = t else { return Err(err("constructor of a non-vector const")) };
                    let st = Ty::Scalar(*s);
                    let mut vals = Vec::new();
                    for a in args {
                        vals.push(lower(e, a, &st, c)?.0);
                    }
                    let tn = e.ty_name(t);
                    (format!("{tn}({})", vals.join(", ")), P_ATOM)
                }
                _ => return Err(err("const values must be literals, vector constructors or arithmetic on them")),
            })
        }
        Ok(lower(self, &c.item.value, t, c)?.0)
    }

    fn struct_order(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut done = BTreeSet::new();
        fn visit(p: &Program, name: &str, done: &mut BTreeSet<String>, out: &mut Vec<String>) {
            if !done.insert(name.to_string()) {
                return;
            }
            if let Some(s) = p.structs.get(name) {
                for f in &s.item.fields {
                    if let Ok(t) = infer::resolve_type(p, &f.ty) {
                        let mut t = &t;
                        while let Ty::Array(e, _) = t {
                            t = e;
                        }
                        if let Ty::Struct(n) = t {
                            visit(p, n, done, out);
                        }
                    }
                }
                out.push(name.to_string());
            }
        }
        // Link order, for determinism.
        let names: Vec<String> = self
            .program
            .modules
            .iter()
            .flat_map(|m| m.items.iter())
            .filter_map(|i| match i {
                ir::Item::Struct(s) if !s.resources && self.structs_used.contains(&s.name) => Some(s.name.clone()),
                _ => None,
            })
            .collect();
        for n in names {
            visit(self.program, &n, &mut done, &mut out);
        }
        out
    }
}

fn op_prec(op: BinOp) -> u8 {
    match op {
        BinOp::Mul | BinOp::Div | BinOp::Rem => P_MUL,
        BinOp::Add | BinOp::Sub => P_ADD,
        BinOp::Shl | BinOp::Shr => P_SHIFT,
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => P_REL,
        BinOp::Eq | BinOp::Ne => P_EQ,
        BinOp::BitAnd => P_BAND,
        BinOp::BitXor => P_BXOR,
        BinOp::BitOr => P_BOR,
        BinOp::And => P_LAND,
        BinOp::Or => P_LOR,
    }
}

/// `x >> k` with a literal `k >= 8` has at most 24 significant bits: exact as f32.
fn fits_in_24_bits(e: &Expr) -> bool {
    match &strip_parens(e).kind {
        K::Binary { op: BinOp::Shr, rhs, .. } => {
            matches!(&strip_parens(rhs).kind, K::Lit(ir::Lit::Int { value, .. }) if *value >= 8)
        }
        K::Lit(ir::Lit::Int { value, .. }) => *value < (1 << 24),
        _ => false,
    }
}

fn scalar_name(s: Scalar, glsl: bool) -> &'static str {
    match (s, glsl) {
        (Scalar::F32, true) => "float",
        (Scalar::I32, true) => "int",
        (Scalar::U32 | Scalar::USize, true) => "uint",
        (Scalar::Bool, true) => "bool",
        (Scalar::F32, false) => "f32",
        (Scalar::I32, false) => "i32",
        (Scalar::U32 | Scalar::USize, false) => "u32",
        (Scalar::Bool, false) => "bool",
    }
}

fn vector_name(s: Scalar, n: u8, glsl: bool) -> String {
    if glsl {
        let p = match s {
            Scalar::F32 => "",
            Scalar::I32 => "i",
            Scalar::U32 | Scalar::USize => "u",
            Scalar::Bool => "b",
        };
        format!("{p}vec{n}")
    } else {
        format!("vec{n}<{}>", scalar_name(s, false))
    }
}

/// `vec3<f32>` → `vec3f` style suffixes for helper names, from the GLSL or WGSL type name.
fn helper_suffix(type_name: &str) -> String {
    match type_name {
        "f32" | "float" => "f32".into(),
        t if t.starts_with("vec") && t.contains('<') => {
            let n = &t[3..4];
            let s = if t.contains("f32") {
                ""
            } else if t.contains("u32") {
                "u"
            } else {
                "i"
            };
            format!("{s}vec{n}")
        }
        t => t.to_string(),
    }
}

fn helper_text(h: &Helper, glsl: bool) -> String {
    let g = glsl;
    match h {
        Helper::U32ToF32 => {
            if g {
                "// u32 as f32, rounded to nearest even like Rust: both halves convert exactly, the sum rounds once.\nfloat lp_u32_to_f32(uint x) {\n    return float(x >> 16u) * 65536.0 + float(x & 65535u);\n}\n".into()
            } else {
                "// u32 as f32, rounded to nearest even like Rust: both halves convert exactly, the sum rounds once.\nfn lp_u32_to_f32(x: u32) -> f32 {\n    return f32(x >> 16u) * 65536.0 + f32(x & 65535u);\n}\n".into()
            }
        }
        Helper::I32ToF32 => {
            if g {
                "// i32 as f32 (magnitude through lp_u32_to_f32, so i32::MIN works).\nfloat lp_i32_to_f32(int x) {\n    if (x < 0) {\n        return -lp_u32_to_f32(0u - uint(x));\n    }\n    return lp_u32_to_f32(uint(x));\n}\n".into()
            } else {
                "// i32 as f32 (magnitude through lp_u32_to_f32, so i32::MIN works).\nfn lp_i32_to_f32(x: i32) -> f32 {\n    if x < 0 {\n        return -lp_u32_to_f32(0u - bitcast<u32>(x));\n    }\n    return lp_u32_to_f32(bitcast<u32>(x));\n}\n".into()
            }
        }
        Helper::F32ToU32 => {
            if g {
                "// f32 as u32 saturates like Rust: NaN and negatives give 0, too large gives u32::MAX.\nuint lp_f32_to_u32(float x) {\n    if (x >= 4294967296.0) {\n        return 4294967295u;\n    }\n    if (x > 0.0) {\n        return uint(x);\n    }\n    return 0u;\n}\n".into()
            } else {
                "// f32 as u32 saturates like Rust: NaN and negatives give 0, too large gives u32::MAX.\nfn lp_f32_to_u32(x: f32) -> u32 {\n    if x >= 4294967296.0 {\n        return 4294967295u;\n    }\n    if x > 0.0 {\n        return u32(x);\n    }\n    return 0u;\n}\n".into()
            }
        }
        Helper::F32ToI32 => {
            if g {
                "// f32 as i32 saturates like Rust: NaN gives 0, out of range gives i32::MIN/MAX.\nint lp_f32_to_i32(float x) {\n    if (x >= 2147483648.0) {\n        return 2147483647;\n    }\n    if (x >= -2147483648.0) {\n        return int(x);\n    }\n    if (x < 0.0) {\n        return -2147483647 - 1;\n    }\n    return 0;\n}\n".into()
            } else {
                "// f32 as i32 saturates like Rust: NaN gives 0, out of range gives i32::MIN/MAX.\nfn lp_f32_to_i32(x: f32) -> i32 {\n    if x >= 2147483648.0 {\n        return 2147483647i;\n    }\n    if x >= -2147483648.0 {\n        return i32(x);\n    }\n    if x < 0.0 {\n        return -2147483647i - 1i;\n    }\n    return 0i;\n}\n".into()
            }
        }
        Helper::DivI32 => "// i32 division truncating toward zero like Rust (GLSL ES leaves negative operands undefined).\nint lp_div_i32(int a, int b) {\n    uint ua = a < 0 ? 0u - uint(a) : uint(a);\n    uint ub = b < 0 ? 0u - uint(b) : uint(b);\n    uint q = ua / ub;\n    return (a < 0) != (b < 0) ? int(0u - q) : int(q);\n}\n".into(),
        Helper::RemI32 => "// i32 remainder with the sign of the dividend, like Rust.\nint lp_rem_i32(int a, int b) {\n    return a - lp_div_i32(a, b) * b;\n}\n".into(),
        Helper::FmodF32 => "// f32 % like WGSL and (up to rounding) Rust: truncated, sign of the dividend; GLSL's mod() floors.\nfloat lp_fmod_f32(float a, float b) {\n    return a - b * trunc(a / b);\n}\n".into(),
        Helper::IsNan => {
            if g {
                "// From the bits: drivers may fold isnan() away under fast-math.\nbool lp_is_nan(float x) {\n    return (floatBitsToUint(x) & 0x7fffffffu) > 0x7f800000u;\n}\n".into()
            } else {
                "// From the bits: drivers may fold NaN checks away under fast-math.\nfn lp_is_nan(x: f32) -> bool {\n    return (bitcast<u32>(x) & 0x7fffffffu) > 0x7f800000u;\n}\n".into()
            }
        }
        Helper::IsInfinite => {
            if g {
                "bool lp_is_infinite(float x) {\n    return (floatBitsToUint(x) & 0x7fffffffu) == 0x7f800000u;\n}\n".into()
            } else {
                "fn lp_is_infinite(x: f32) -> bool {\n    return (bitcast<u32>(x) & 0x7fffffffu) == 0x7f800000u;\n}\n".into()
            }
        }
        Helper::IsFinite => {
            if g {
                "bool lp_is_finite(float x) {\n    return (floatBitsToUint(x) & 0x7f800000u) != 0x7f800000u;\n}\n".into()
            } else {
                "fn lp_is_finite(x: f32) -> bool {\n    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;\n}\n".into()
            }
        }
        Helper::Signum => {
            if g {
                "// Rust's signum: 1.0 for +0.0, -1.0 for -0.0, NaN stays NaN (GLSL's sign(0.0) is 0.0).\nfloat lp_signum(float x) {\n    if (lp_is_nan(x)) {\n        return x;\n    }\n    return (floatBitsToUint(x) & 0x80000000u) != 0u ? -1.0 : 1.0;\n}\n".into()
            } else {
                "// Rust's signum: 1.0 for +0.0, -1.0 for -0.0, NaN stays NaN (WGSL's sign(0.0) is 0.0).\nfn lp_signum(x: f32) -> f32 {\n    if lp_is_nan(x) {\n        return x;\n    }\n    return select(1.0, -1.0, (bitcast<u32>(x) & 0x80000000u) != 0u);\n}\n".into()
            }
        }
        Helper::Round => {
            if g {
                "// Rust's round: halves away from zero (GLSL's round() may pick either).\nfloat lp_round(float x) {\n    float t = trunc(x);\n    if (abs(x - t) >= 0.5) {\n        t += sign(x);\n    }\n    return t;\n}\n".into()
            } else {
                "// Rust's round: halves away from zero (WGSL's round() goes to even).\nfn lp_round(x: f32) -> f32 {\n    var t: f32 = trunc(x);\n    if abs(x - t) >= 0.5 {\n        t += sign(x);\n    }\n    return t;\n}\n".into()
            }
        }
        Helper::Fract(t) => {
            let s = helper_suffix(t);
            if g {
                format!("// Rust's fract: x - trunc(x) (GLSL's fract() is x - floor(x)).\n{t} lp_fract_{s}({t} x) {{\n    return x - trunc(x);\n}}\n")
            } else {
                format!("// Rust's fract: x - trunc(x) (WGSL's fract() is x - floor(x)).\nfn lp_fract_{s}(x: {t}) -> {t} {{\n    return x - trunc(x);\n}}\n")
            }
        }
        Helper::LengthSquared(t) => {
            let s = helper_suffix(t);
            if g {
                format!("float lp_length_squared_{s}({t} v) {{\n    return dot(v, v);\n}}\n")
            } else {
                format!("fn lp_length_squared_{s}(v: {t}) -> f32 {{\n    return dot(v, v);\n}}\n")
            }
        }
        Helper::Reduce { op, ty, n } => {
            let s = helper_suffix(ty);
            let name = match *op {
                "min" => "min_element",
                "max" => "max_element",
                "+" => "element_sum",
                _ => "element_product",
            };
            let comps: Vec<String> = "xyzw"[..*n as usize].chars().map(|c| format!("v.{c}")).collect();
            // glam folds left to right: ((x op y) op z).
            let mut expr = comps[0].clone();
            for c in &comps[1..] {
                expr = if op.len() > 1 { format!("{op}({expr}, {c})") } else { format!("{expr} {op} {c}") };
            }
            let scalar = if ty.contains("uvec") || ty.contains("u32") {
                if g { "uint" } else { "u32" }
            } else if ty.contains("ivec") || ty.contains("i32") {
                if g { "int" } else { "i32" }
            } else if g {
                "float"
            } else {
                "f32"
            };
            if g {
                format!("{scalar} lp_{name}_{s}({ty} v) {{\n    return {expr};\n}}\n")
            } else {
                format!("fn lp_{name}_{s}(v: {ty}) -> {scalar} {{\n    return {expr};\n}}\n")
            }
        }
        Helper::FetchVec4 => "// Texel `i` of a row-major RGBA32F data texture.\nvec4 lp_fetch_vec4(highp sampler2D t, uint i) {\n    uint w = uint(textureSize(t, 0).x);\n    return texelFetch(t, ivec2(int(i % w), int(i / w)), 0);\n}\n".into(),
        Helper::FetchUVec4 => "// Texel `i` of a row-major RGBA32UI data texture.\nuvec4 lp_fetch_uvec4(highp usampler2D t, uint i) {\n    uint w = uint(textureSize(t, 0).x);\n    return texelFetch(t, ivec2(int(i % w), int(i / w)), 0);\n}\n".into(),
    }
}
