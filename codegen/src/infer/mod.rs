//! Type inference for one kernel function.
//!
//! rustc has already accepted the same code, so this only has to agree with it: types flow
//! bottom-up from literals, variables, signatures and the built-in table; integer literals
//! without a suffix are type variables unified with the types they meet (as rustc's
//! `{integer}`), defaulting to `i32`. Every expression's type and every name's binding are
//! recorded for the emitter, which also takes each binding's output name from here.

mod calls;

use std::collections::{BTreeSet, HashMap};

use crate::ir::{self, Expr, ExprKind as K, Span};
use crate::names;
use crate::types::{self, Scalar, Ty, BOOL, F32, I32, U32, USIZE};
use crate::{CodegenError, Located, Program};

pub(crate) type Key = usize;

pub(crate) fn key(e: &Expr) -> Key {
    e as *const Expr as usize
}

pub(crate) fn stmt_key(s: &ir::Stmt) -> Key {
    s as *const ir::Stmt as usize
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum BindingKind {
    Local,
    /// A by-value parameter (`mutable`: declared `mut x: T`).
    Param,
    /// A `&mut T` parameter.
    RefParam,
    /// A `&Resources` parameter: vanishes in shaders.
    Resource,
}

#[derive(Clone, Debug)]
pub(crate) struct Binding {
    /// The name in generated code (unique in the function, never a target keyword).
    pub out_name: String,
    pub ty: Ty,
    pub mutable: bool,
    pub kind: BindingKind,
}

/// What inference learned about one function.
#[derive(Debug, Default)]
pub(crate) struct FnTypes {
    pub types: HashMap<Key, Ty>,
    pub bindings: Vec<Binding>,
    /// Path expression → binding it names.
    pub uses: HashMap<Key, usize>,
    /// `let` statement → binding it declares.
    pub lets: HashMap<Key, usize>,
    /// `for` expression → binding of its loop variable.
    pub for_vars: HashMap<Key, usize>,
    pub params: Vec<usize>,
    pub ret: Ty,
}

impl FnTypes {
    pub fn ty(&self, e: &Expr) -> &Ty {
        self.types.get(&key(e)).unwrap_or(&Ty::Unit)
    }
}

struct Cx<'a> {
    program: &'a Program,
    func: &'a Located<ir::FnDef>,
    out: FnTypes,
    scopes: Vec<Vec<(String, usize)>>,
    /// Union-find over integer type variables: each entry is a link, a root, or a type.
    vars: Vec<Ty>,
    used_names: BTreeSet<String>,
}

pub(crate) fn infer_fn(program: &Program, func: &Located<ir::FnDef>) -> Result<FnTypes, CodegenError> {
    let mut cx =
        Cx { program, func, out: FnTypes::default(), scopes: vec![vec![]], vars: vec![], used_names: BTreeSet::new() };
    let f = &func.item;
    for p in &f.params {
        let ty = cx.resolve_type(&p.ty, p.span)?;
        let kind = match &ty {
            Ty::RefMut(_) => BindingKind::RefParam,
            Ty::Resource(_) => BindingKind::Resource,
            _ => BindingKind::Param,
        };
        let id = cx.bind(&p.name, ty, p.mutable, kind);
        cx.out.params.push(id);
    }
    cx.out.ret = match &f.ret {
        Some(t) => cx.resolve_type(t, f.span)?,
        None => Ty::Unit,
    };
    if matches!(cx.out.ret, Ty::Resource(_) | Ty::RefMut(_) | Ty::Texels(_) | Ty::Storage(_) | Ty::Atomics) {
        return Err(cx.error(f.span, "kernel functions return values: not references or resources"));
    }
    let body_ty = cx.block(&f.body)?;
    let ret = cx.out.ret.clone();
    if f.body.tail.is_some() {
        cx.unify(&body_ty, &ret, f.span)?;
    }
    // Resolve every recorded type now that all constraints are in.
    let types: Vec<(Key, Ty)> = cx.out.types.iter().map(|(k, t)| (*k, t.clone())).collect();
    for (k, t) in types {
        let r = cx.finalize(&t);
        cx.out.types.insert(k, r);
    }
    for i in 0..cx.out.bindings.len() {
        let t = cx.out.bindings[i].ty.clone();
        cx.out.bindings[i].ty = cx.finalize(&t);
    }
    Ok(cx.out)
}

impl<'a> Cx<'a> {
    fn error(&self, span: Span, msg: impl Into<String>) -> CodegenError {
        CodegenError {
            file: self.func.file.clone(),
            span,
            function: Some(format!("{}::{}", self.func.module, self.func.item.name)),
            message: msg.into(),
        }
    }

    fn bind(&mut self, name: &str, ty: Ty, mutable: bool, kind: BindingKind) -> usize {
        let program = self.program;
        let out_name = names::unique_local(name, &mut self.used_names, |n| program.is_global_name(n));
        let id = self.out.bindings.len();
        self.out.bindings.push(Binding { out_name, ty, mutable, kind });
        self.scopes.last_mut().expect("a scope").push((name.to_string(), id));
        id
    }

    fn lookup(&self, name: &str) -> Option<usize> {
        self.scopes.iter().rev().flat_map(|s| s.iter().rev()).find(|(n, _)| n == name).map(|(_, id)| *id)
    }

    pub(crate) fn resolve_type(&self, t: &ir::Type, span: Span) -> Result<Ty, CodegenError> {
        resolve_type(self.program, t).map_err(|m| self.error(span, m))
    }

    fn new_var(&mut self) -> Ty {
        let id = self.vars.len() as u32;
        self.vars.push(Ty::IntVar(id));
        Ty::IntVar(id)
    }

    /// Follows integer-variable links to a representative.
    fn shallow(&self, t: &Ty) -> Ty {
        let mut t = t.clone();
        while let Ty::IntVar(v) = t {
            let next = &self.vars[v as usize];
            if *next == Ty::IntVar(v) {
                return t;
            }
            t = next.clone();
        }
        t
    }

    fn finalize(&self, t: &Ty) -> Ty {
        match self.shallow(t) {
            Ty::IntVar(_) => I32,
            Ty::Array(e, n) => Ty::Array(Box::new(self.finalize(&e)), n),
            Ty::RefMut(e) => Ty::RefMut(Box::new(self.finalize(&e))),
            other => other,
        }
    }

    fn unify(&mut self, a: &Ty, b: &Ty, span: Span) -> Result<Ty, CodegenError> {
        let (a, b) = (self.shallow(a), self.shallow(b));
        match (&a, &b) {
            _ if a == b => Ok(a),
            (Ty::Never, _) => Ok(b),
            (_, Ty::Never) => Ok(a),
            (Ty::IntVar(v), other) | (other, Ty::IntVar(v)) if other.is_int() => {
                self.vars[*v as usize] = other.clone();
                Ok(other.clone())
            }
            (Ty::Array(x, n), Ty::Array(y, m)) if n == m => {
                let e = self.unify(x, y, span)?;
                Ok(Ty::Array(Box::new(e), *n))
            }
            (Ty::RefMut(x), Ty::RefMut(y)) => {
                let e = self.unify(x, y, span)?;
                Ok(Ty::RefMut(Box::new(e)))
            }
            _ => Err(self.error(
                span,
                format!("type mismatch: `{a}` and `{b}` (codegen's inference disagrees with rustc here)"),
            )),
        }
    }

    fn record(&mut self, e: &Expr, t: Ty) -> Ty {
        self.out.types.insert(key(e), t.clone());
        t
    }

    fn block(&mut self, b: &ir::Block) -> Result<Ty, CodegenError> {
        self.scopes.push(vec![]);
        let mut diverges = false;
        for s in &b.stmts {
            match s {
                ir::Stmt::Let { name, mutable, ty, init, span } => {
                    let mut t = match ty {
                        Some(t) => self.resolve_type(t, *span)?,
                        None => Ty::Never,
                    };
                    if let Some(init) = init {
                        let it = self.expr(init)?;
                        t = self.unify(&t, &it, init.span)?;
                    }
                    if t == Ty::Never {
                        return Err(self.error(*span, "give this `let` a type or an initial value"));
                    }
                    if matches!(t, Ty::Resource(_) | Ty::Texels(_) | Ty::Storage(_) | Ty::Atomics) {
                        return Err(self
                            .error(*span, "resources cannot be bound to local variables: use `scene.field` directly"));
                    }
                    let id = self.bind(name, t, *mutable, BindingKind::Local);
                    self.out.lets.insert(stmt_key(s), id);
                }
                ir::Stmt::Expr(e) => {
                    let t = self.expr(e)?;
                    if t == Ty::Never {
                        diverges = true;
                    }
                }
            }
        }
        let t = match &b.tail {
            Some(t) => self.expr(t)?,
            None if diverges => Ty::Never,
            None => Ty::Unit,
        };
        self.scopes.pop();
        Ok(t)
    }

    fn expr(&mut self, e: &Expr) -> Result<Ty, CodegenError> {
        let t = self.expr_inner(e)?;
        Ok(self.record(e, t))
    }

    /// The type of one expression, before [`Self::expr`] records it: the forms that take a few
    /// lines here, the others through the helper named after the form.
    fn expr_inner(&mut self, e: &Expr) -> Result<Ty, CodegenError> {
        let span = e.span;
        Ok(match &e.kind {
            K::Lit(ir::Lit::Bool(_)) => BOOL,
            K::Lit(ir::Lit::Float { .. }) => F32,
            K::Lit(ir::Lit::Int { suffix, .. }) => match suffix.as_deref() {
                Some("u32") => U32,
                Some("i32") => I32,
                Some("usize") => USIZE,
                _ => self.new_var(),
            },
            K::Path(path) => self.path(e, path)?,
            K::Paren(inner) => self.expr(inner)?,
            // Operators.
            K::Unary { op, expr } => self.unary_expr(*op, expr, span)?,
            K::Binary { op, lhs, rhs } => {
                let l = self.expr(lhs)?;
                let r = self.expr(rhs)?;
                self.binary(*op, &l, &r, span)?
            }
            K::Assign { op, place, value } => self.assign_expr(*op, place, value, span)?,
            K::Cast { expr, ty } => self.cast_expr(expr, ty, span)?,
            // Calls.
            K::Call { path, args } => self.call(path, args, span)?,
            K::MethodCall { receiver, method, args } => {
                let r = self.expr(receiver)?;
                let r = self.shallow(&r).strip_ref().clone();
                self.method(&r, method, args, span)?
            }
            // Places and data.
            K::Field { base, field } => {
                let b = self.expr(base)?;
                let b = self.shallow(&b).strip_ref().clone();
                self.field(&b, field, span)?
            }
            K::Index { base, index } => self.index_expr(base, index, span)?,
            K::StructLit { name, fields } => self.struct_lit_expr(name, fields, span)?,
            K::Array(elems) => self.array_expr(elems)?,
            K::ArrayRepeat { value, len } => self.array_repeat_expr(value, len, span)?,
            K::AddrOfMut(place) => self.addr_of_mut_expr(place)?,
            K::AddrOf(place) => self.addr_of_expr(place, span)?,
            // Control flow.
            K::If { cond, then, otherwise } => self.if_expr(cond, then, otherwise.as_deref(), span)?,
            K::Match { scrutinee, arms } => self.match_expr(scrutinee, arms, span)?,
            K::Block(b) => self.block(b)?,
            K::While { cond, body } => self.while_expr(cond, body)?,
            K::Loop { body } => self.loop_expr(body)?,
            K::ForRange { var, start, end, body, .. } => self.for_range_expr(e, var, start, end, body)?,
            K::Break | K::Continue => Ty::Never,
            K::Return(v) => self.return_expr(v.as_deref(), span)?,
        })
    }

    /// `-x`, `!x` (the operand's type) and `*x` (the type behind a `&mut` parameter).
    fn unary_expr(&mut self, op: ir::UnOp, operand: &Expr, span: Span) -> Result<Ty, CodegenError> {
        let t = self.expr(operand)?;
        Ok(match op {
            ir::UnOp::Deref => match self.shallow(&t) {
                Ty::RefMut(inner) => *inner,
                other => return Err(self.error(span, format!("`*` needs a `&mut` parameter, found `{other}`"))),
            },
            _ => t,
        })
    }

    /// `place = value` and `place op= value`: the value has the place's type, except for shifts
    /// (any integer amount) and a vector place combined with a scalar (`v *= 2.0`).
    fn assign_expr(
        &mut self,
        op: Option<ir::BinOp>,
        place: &Expr,
        value: &Expr,
        span: Span,
    ) -> Result<Ty, CodegenError> {
        let p = self.expr(place)?;
        let v = self.expr(value)?;
        let p = self.shallow(&p);
        let p = p.strip_ref().clone();
        match op {
            Some(ir::BinOp::Shl | ir::BinOp::Shr) => {}
            Some(_) if matches!(p, Ty::Vector(..)) && !matches!(self.shallow(&v), Ty::Vector(..)) => {}
            _ => {
                self.unify(&p, &v, span)?;
            }
        }
        Ok(Ty::Unit)
    }

    /// `x as T`: between scalar types only.
    fn cast_expr(&mut self, operand: &Expr, ty: &ir::Type, span: Span) -> Result<Ty, CodegenError> {
        let from = self.expr(operand)?;
        let to = self.resolve_type(ty, span)?;
        let from = self.shallow(&from);
        if !matches!(to, Ty::Scalar(_)) || !matches!(from, Ty::Scalar(_) | Ty::IntVar(_)) {
            return Err(self.error(span, format!("`as` casts between scalar types only (found `{from}` as `{to}`)")));
        }
        Ok(to)
    }

    /// `base[index]`: an array's element, at a `usize` index.
    fn index_expr(&mut self, base: &Expr, index: &Expr, span: Span) -> Result<Ty, CodegenError> {
        let b = self.expr(base)?;
        let i = self.expr(index)?;
        self.unify(&i, &USIZE, index.span)?;
        match self.shallow(&b).strip_ref() {
            Ty::Array(elem, _) => Ok((**elem).clone()),
            other => Err(self.error(span, format!("only arrays can be indexed, found `{other}`"))),
        }
    }

    /// `Name { field: value, .. }`: a kernel struct (not the host-built `#[resources]` one),
    /// each value of its field's type.
    fn struct_lit_expr(&mut self, name: &str, fields: &[(String, Expr)], span: Span) -> Result<Ty, CodegenError> {
        let Some(def) = self.program.structs.get(name) else {
            return Err(self.error(span, format!("unknown kernel struct `{name}`")));
        };
        if def.item.resources {
            return Err(self.error(span, "a `#[resources]` struct is built by the host, not by kernel code"));
        }
        let def = def.item.clone();
        for (fname, value) in fields {
            let Some(field) = def.fields.iter().find(|f| &f.name == fname) else {
                return Err(self.error(value.span, format!("`{name}` has no field `{fname}`")));
            };
            let ft = self.resolve_type(&field.ty, field.span)?;
            let vt = self.expr(value)?;
            self.unify(&ft, &vt, value.span)?;
        }
        Ok(Ty::Struct(name.to_string()))
    }

    /// `[a, b, ..]`: every element of one type.
    fn array_expr(&mut self, elems: &[Expr]) -> Result<Ty, CodegenError> {
        let mut t = Ty::Never;
        for el in elems {
            let et = self.expr(el)?;
            t = self.unify(&t, &et, el.span)?;
        }
        Ok(Ty::Array(Box::new(t), elems.len() as u32))
    }

    /// `[value; len]`: `len` a literal or a kernel const.
    fn array_repeat_expr(&mut self, value: &Expr, len: &ir::ArrayLen, span: Span) -> Result<Ty, CodegenError> {
        let t = self.expr(value)?;
        let n = array_len(self.program, len).map_err(|m| self.error(span, m))?;
        Ok(Ty::Array(Box::new(t), n))
    }

    /// `&mut place`.
    fn addr_of_mut_expr(&mut self, place: &Expr) -> Result<Ty, CodegenError> {
        let t = self.expr(place)?;
        Ok(match self.shallow(&t) {
            // `&mut *state` re-borrows a `&mut` parameter.
            Ty::RefMut(inner) => Ty::RefMut(inner),
            other => Ty::RefMut(Box::new(other)),
        })
    }

    /// `&place`: only of the `#[resources]` struct, to pass it on.
    fn addr_of_expr(&mut self, place: &Expr, span: Span) -> Result<Ty, CodegenError> {
        let t = self.expr(place)?;
        match t {
            Ty::Resource(_) => Ok(t),
            other => Err(self.error(
                span,
                format!("shared references are only for the `#[resources]` struct; pass `{other}` by value (it is Copy) or as `&mut`"),
            )),
        }
    }

    /// `if cond { .. } else ..`: a `bool` condition; both branches of one type, `()` without
    /// `else`.
    fn if_expr(
        &mut self,
        cond: &Expr,
        then: &ir::Block,
        otherwise: Option<&Expr>,
        span: Span,
    ) -> Result<Ty, CodegenError> {
        let c = self.expr(cond)?;
        self.unify(&c, &BOOL, cond.span)?;
        let t = self.block(then)?;
        Ok(match otherwise {
            Some(o) => {
                let ot = self.expr(o)?;
                self.unify(&t, &ot, span)?
            }
            None => Ty::Unit,
        })
    }

    /// `match scrutinee { .. }`: on an integer, patterns of its type, every arm of one type.
    fn match_expr(&mut self, scrutinee: &Expr, arms: &[ir::MatchArm], span: Span) -> Result<Ty, CodegenError> {
        let s = self.expr(scrutinee)?;
        if !self.shallow(&s).is_int() {
            return Err(self.error(span, "`match` in kernels is on integers only"));
        }
        let mut t = Ty::Never;
        for arm in arms {
            for p in &arm.patterns {
                let pt = self.expr(p)?;
                self.unify(&s, &pt, p.span)?;
            }
            let bt = self.expr(&arm.body)?;
            t = self.unify(&t, &bt, arm.body.span)?;
        }
        Ok(t)
    }

    /// `while cond { .. }`: a `bool` condition.
    fn while_expr(&mut self, cond: &Expr, body: &ir::Block) -> Result<Ty, CodegenError> {
        let c = self.expr(cond)?;
        self.unify(&c, &BOOL, cond.span)?;
        self.block(body)?;
        Ok(Ty::Unit)
    }

    /// `loop { .. }`.
    fn loop_expr(&mut self, body: &ir::Block) -> Result<Ty, CodegenError> {
        self.block(body)?;
        // A `loop` without `break` never ends normally (rustc types it `!`).
        Ok(if loop_has_break(body) { Ty::Unit } else { Ty::Never })
    }

    /// `for var in start..end { .. }` (`e`): both ends of one integer type, the loop variable's,
    /// bound in a scope of its own and recorded for `e`.
    fn for_range_expr(
        &mut self,
        e: &Expr,
        var: &str,
        start: &Expr,
        end: &Expr,
        body: &ir::Block,
    ) -> Result<Ty, CodegenError> {
        let span = e.span;
        let s = self.expr(start)?;
        let en = self.expr(end)?;
        let t = self.unify(&s, &en, span)?;
        if !self.shallow(&t).is_int() {
            return Err(self.error(span, "`for` ranges are over integers"));
        }
        self.scopes.push(vec![]);
        let id = self.bind(var, t, false, BindingKind::Local);
        self.out.for_vars.insert(key(e), id);
        self.block(body)?;
        self.scopes.pop();
        Ok(Ty::Unit)
    }

    /// `return value`: the value (`()` without one) of the function's return type.
    fn return_expr(&mut self, value: Option<&Expr>, span: Span) -> Result<Ty, CodegenError> {
        let t = match value {
            Some(v) => self.expr(v)?,
            None => Ty::Unit,
        };
        let ret = self.out.ret.clone();
        self.unify(&t, &ret, span)?;
        Ok(Ty::Never)
    }

    fn path(&mut self, e: &Expr, path: &[String]) -> Result<Ty, CodegenError> {
        if path.len() == 1 {
            let name = &path[0];
            if let Some(id) = self.lookup(name) {
                self.out.uses.insert(key(e), id);
                return Ok(self.out.bindings[id].ty.clone());
            }
            if let Some(c) = self.program.consts.get(name) {
                return self.resolve_type(&c.item.ty, e.span);
            }
            return Err(self.error(e.span, format!("`{name}` is not a variable or kernel const")));
        }
        if let Some((t, _)) = types::assoc_const(path) {
            return Ok(t);
        }
        // A const of another kernel module through its path.
        if let Some(c) = path.last().and_then(|n| self.program.consts.get(n)) {
            return self.resolve_type(&c.item.ty, e.span);
        }
        Err(self.error(e.span, format!("`{}` is not supported in kernels", path.join("::"))))
    }

    fn binary(&mut self, op: ir::BinOp, l: &Ty, r: &Ty, span: Span) -> Result<Ty, CodegenError> {
        use ir::BinOp as B;
        let (l, r) = (self.shallow(l), self.shallow(r));
        Ok(match op {
            B::And | B::Or => {
                self.unify(&l, &BOOL, span)?;
                self.unify(&r, &BOOL, span)?;
                BOOL
            }
            B::Eq | B::Ne | B::Lt | B::Le | B::Gt | B::Ge => {
                self.unify(&l, &r, span)?;
                BOOL
            }
            B::Shl | B::Shr => {
                if !r.is_int() {
                    return Err(self.error(span, "shift amounts are integers"));
                }
                l
            }
            _ => match (&l, &r) {
                (Ty::Vector(..), Ty::Vector(..)) => self.unify(&l, &r, span)?,
                (Ty::Vector(s, _), other) | (other, Ty::Vector(s, _)) => {
                    self.unify(other, &Ty::Scalar(*s), span)?;
                    if matches!(l, Ty::Vector(..)) {
                        l.clone()
                    } else {
                        r.clone()
                    }
                }
                _ => self.unify(&l, &r, span)?,
            },
        })
    }
}

fn loop_has_break(body: &ir::Block) -> bool {
    // `break` inside nested loops belongs to them.
    fn in_expr(e: &Expr) -> bool {
        match &e.kind {
            K::Break => true,
            K::While { .. } | K::Loop { .. } | K::ForRange { .. } => false,
            K::If { cond, then, otherwise } => {
                in_expr(cond) || in_block(then) || otherwise.as_ref().is_some_and(|o| in_expr(o))
            }
            K::Block(b) => in_block(b),
            K::Match { arms, .. } => arms.iter().any(|a| in_expr(&a.body)),
            _ => false,
        }
    }
    fn in_block(b: &ir::Block) -> bool {
        b.stmts.iter().any(|s| match s {
            ir::Stmt::Expr(e) => in_expr(e),
            ir::Stmt::Let { init: Some(e), .. } => in_expr(e),
            _ => false,
        }) || b.tail.as_ref().is_some_and(|t| in_expr(t))
    }
    in_block(body)
}

pub(crate) fn array_len(program: &Program, len: &ir::ArrayLen) -> Result<u32, String> {
    match len {
        ir::ArrayLen::Literal(n) => Ok(*n),
        ir::ArrayLen::Const(name) => match program.consts.get(name).map(|c| &c.item.value.kind) {
            Some(K::Lit(ir::Lit::Int { value, .. })) => {
                u32::try_from(*value).map_err(|_| "array length out of range".to_string())
            }
            Some(_) => Err(format!("array length `{name}` must be a const with an integer literal value")),
            None => Err(format!("unknown const `{name}`")),
        },
    }
}

pub(crate) fn resolve_type(program: &Program, t: &ir::Type) -> Result<Ty, String> {
    match t {
        ir::Type::Named { name, args } => {
            if let Some(b) = Ty::builtin(name) {
                if !args.is_empty() {
                    return Err(format!("`{name}` takes no type arguments"));
                }
                return Ok(b);
            }
            if name == "Texels" {
                let [elem] = args.as_slice() else {
                    return Err("`Texels` takes one type argument: `Texels<Vec4>` or `Texels<UVec4>`".into());
                };
                let e = resolve_type(program, elem)?;
                if !matches!(e, Ty::Vector(Scalar::F32 | Scalar::U32, 4)) {
                    return Err(format!(
                        "`Texels<{e}>` is not supported: use `Texels<Vec4>` (RGBA32F) or `Texels<UVec4>` (RGBA32UI)"
                    ));
                }
                return Ok(Ty::Texels(Box::new(e)));
            }
            if name == "Storage" {
                let [elem] = args.as_slice() else {
                    return Err("`Storage` takes one type argument: `Storage<Vec4>`, `Storage<UVec4>`, `Storage<u32>` or `Storage<f32>`".into());
                };
                let e = resolve_type(program, elem)?;
                if !matches!(e, Ty::Vector(Scalar::F32 | Scalar::U32, 4) | Ty::Scalar(Scalar::F32 | Scalar::U32)) {
                    return Err(format!(
                        "`Storage<{e}>` is not supported: use `Storage<Vec4>`, `Storage<UVec4>`, `Storage<u32>` or `Storage<f32>`"
                    ));
                }
                return Ok(Ty::Storage(Box::new(e)));
            }
            if name == "Atomics" {
                if !args.is_empty() {
                    return Err("`Atomics` takes no type arguments (its counters are u32)".into());
                }
                return Ok(Ty::Atomics);
            }
            match program.structs.get(name) {
                Some(s) if s.item.resources => Ok(Ty::Resource(name.clone())),
                Some(_) => Ok(Ty::Struct(name.clone())),
                None => {
                    Err(format!("unknown type `{name}` (not a glam/scalar type or a struct of a linked kernel module)"))
                }
            }
        }
        ir::Type::Array { elem, len } => {
            let e = resolve_type(program, elem)?;
            Ok(Ty::Array(Box::new(e), array_len(program, len)?))
        }
        ir::Type::Ref { mutable: true, inner } => {
            let i = resolve_type(program, inner)?;
            if matches!(i, Ty::Resource(_)) {
                return Err("pass resources as `&Resources`, not `&mut`".into());
            }
            Ok(Ty::RefMut(Box::new(i)))
        }
        ir::Type::Ref { mutable: false, inner } => match resolve_type(program, inner)? {
            r @ Ty::Resource(_) => Ok(r),
            other => Err(format!(
                "`&{other}`: shared references are only for the `#[resources]` struct; pass values by value"
            )),
        },
    }
}
