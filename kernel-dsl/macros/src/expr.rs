//! Statements and expressions: blocks, `let`, every supported expression form, literals and
//! paths, lowered to IR, and the messages for the Rust the DSL does not support.

use kernel_dsl_ir as ir;
use quote::quote;
use syn::spanned::Spanned;

use crate::types::unsupported_type_message;
use crate::{err, err_at, is_screaming_case, span_of, Lowering};

impl Lowering {
    pub(crate) fn block(&mut self, b: &syn::Block) -> Option<ir::Block> {
        let mut out = ir::Block::default();
        let n = b.stmts.len();
        let mut ok = true;
        for (i, s) in b.stmts.iter().enumerate() {
            match s {
                syn::Stmt::Local(l) => ok &= self.local(l, &mut out.stmts).is_some(),
                syn::Stmt::Item(item) => {
                    self.error(err_at(
                        &item,
                        "items inside function bodies are not supported: move it to the module level",
                    ));
                    ok = false;
                }
                syn::Stmt::Expr(e, semi) => match self.expr(e) {
                    Some(e) if semi.is_none() && i + 1 == n && !is_statement_like(&e) => out.tail = Some(Box::new(e)),
                    Some(e) => out.stmts.push(ir::Stmt::Expr(e)),
                    None => ok = false,
                },
                syn::Stmt::Macro(m) => {
                    self.error(err_at(&m.mac.path, macro_message(&m.mac)));
                    ok = false;
                }
            }
        }
        ok.then_some(out)
    }

    pub(crate) fn local(&mut self, l: &syn::Local, out: &mut Vec<ir::Stmt>) -> Option<()> {
        if let Some((else_token, _)) = l.init.as_ref().and_then(|init| init.diverge.as_ref()) {
            self.error(err(else_token.span, "`let ... else` is not supported in kernels: test the value with `if`"));
            return None;
        }
        let (pat, ty) = match &l.pat {
            syn::Pat::Type(pt) => (&*pt.pat, Some(&*pt.ty)),
            p => (p, None),
        };
        let (name, mutable) = match pat {
            syn::Pat::Ident(pi) if pi.by_ref.is_none() && pi.subpat.is_none() => {
                (pi.ident.to_string(), pi.mutability.is_some())
            }
            syn::Pat::Tuple(_) | syn::Pat::Struct(_) | syn::Pat::TupleStruct(_) | syn::Pat::Slice(_) => {
                self.error(err_at(&pat, "destructuring is not supported in kernels: bind one name per `let`"));
                return None;
            }
            other => {
                self.error(err_at(&other, "`let` needs a plain name here: `let x = ...;` or `let mut x: f32 = ...;`"));
                return None;
            }
        };
        let ty = match ty {
            Some(t) => Some(self.ty(t)?),
            None => None,
        };
        let init = match &l.init {
            None => None,
            Some(init) => Some(self.expr(&init.expr)?),
        };
        out.push(ir::Stmt::Let { name, mutable, ty, init, span: span_of(l.let_token.span) });
        Some(())
    }

    pub(crate) fn boxed(&mut self, e: &syn::Expr) -> Option<Box<ir::Expr>> {
        self.expr(e).map(Box::new)
    }

    /// Lowers one expression: the forms that take a line here, the others through the helper
    /// named after the form, and everything else the DSL rejects through
    /// [`Self::report_unsupported_expr`].
    pub(crate) fn expr(&mut self, e: &syn::Expr) -> Option<ir::Expr> {
        let span = span_of(e.span());
        let kind = match e {
            syn::Expr::Lit(l) => ir::ExprKind::Lit(self.lit(&l.lit)?),
            syn::Expr::Path(p) => ir::ExprKind::Path(self.path(&p.qself, &p.path)?),
            syn::Expr::Paren(p) => ir::ExprKind::Paren(self.boxed(&p.expr)?),
            syn::Expr::Group(g) => return self.expr(&g.expr),
            // Operators.
            syn::Expr::Unary(u) => self.unary_expr(u)?,
            syn::Expr::Binary(b) => self.binary_expr(b)?,
            syn::Expr::Assign(a) => self.assign_expr(a)?,
            syn::Expr::Cast(c) => self.cast_expr(c)?,
            // Calls.
            syn::Expr::Call(c) => self.call_expr(c)?,
            syn::Expr::MethodCall(m) => self.method_call_expr(m)?,
            // Places and data.
            syn::Expr::Field(f) => self.field_expr(f)?,
            syn::Expr::Index(i) => self.index_expr(i)?,
            syn::Expr::Struct(s) => self.struct_expr(s)?,
            syn::Expr::Array(a) => ir::ExprKind::Array(self.exprs(a.elems.iter())?),
            syn::Expr::Repeat(r) => self.repeat_expr(r)?,
            syn::Expr::Reference(r) => self.reference_expr(r)?,
            // Control flow.
            syn::Expr::If(i) => self.if_expr(i)?,
            syn::Expr::Match(m) => self.match_expr(m)?,
            syn::Expr::Block(b) => self.block_expr(b)?,
            syn::Expr::While(w) => self.while_expr(w)?,
            syn::Expr::Loop(l) => self.loop_expr(l)?,
            syn::Expr::ForLoop(f) => self.for_range_expr(f)?,
            syn::Expr::Break(b) => self.break_expr(b)?,
            syn::Expr::Continue(c) => self.continue_expr(c)?,
            syn::Expr::Return(r) => ir::ExprKind::Return(match &r.expr {
                None => None,
                Some(v) => Some(self.boxed(v)?),
            }),
            other => {
                self.report_unsupported_expr(other);
                return None;
            }
        };
        Some(ir::Expr { kind, span })
    }

    /// `-x`, `!x`, `*x`.
    fn unary_expr(&mut self, u: &syn::ExprUnary) -> Option<ir::ExprKind> {
        let op = match u.op {
            syn::UnOp::Neg(_) => ir::UnOp::Neg,
            syn::UnOp::Not(_) => ir::UnOp::Not,
            syn::UnOp::Deref(_) => ir::UnOp::Deref,
            _ => {
                self.error(err_at(u, "this operator is not supported in kernels"));
                return None;
            }
        };
        Some(ir::ExprKind::Unary { op, expr: self.boxed(&u.expr)? })
    }

    /// `a + b`, and the compound assignments (`a += b`), which syn parses as binary operators.
    /// Shifts by a non-literal amount are rejected: the DSL masks them through
    /// `wrapping_shl`/`wrapping_shr`.
    fn binary_expr(&mut self, b: &syn::ExprBinary) -> Option<ir::ExprKind> {
        let Some((op, assign)) = bin_op(&b.op) else {
            self.error(err_at(&b.op, "this operator is not supported in kernels"));
            return None;
        };
        if matches!(op, ir::BinOp::Shl | ir::BinOp::Shr) && !is_int_literal(&b.right) {
            let (shift, amount) = (&b.op, &b.right);
            self.error(err_at(
                &quote!(#shift #amount),
                "shift amounts that are not literals must use `wrapping_shl`/`wrapping_shr`: a shift by 32 or more panics in Rust and is undefined in GLSL, the DSL masks it to 0..31",
            ));
            return None;
        }
        // Both sides are lowered before either error ends it, so both report.
        let lhs = self.boxed(&b.left);
        let rhs = self.boxed(&b.right);
        let (lhs, rhs) = (lhs?, rhs?);
        Some(if assign {
            ir::ExprKind::Assign { op: Some(op), place: lhs, value: rhs }
        } else {
            ir::ExprKind::Binary { op, lhs, rhs }
        })
    }

    /// `place = value`.
    fn assign_expr(&mut self, a: &syn::ExprAssign) -> Option<ir::ExprKind> {
        let place = self.boxed(&a.left);
        let value = self.boxed(&a.right);
        Some(ir::ExprKind::Assign { op: None, place: place?, value: value? })
    }

    /// `x as T`.
    fn cast_expr(&mut self, c: &syn::ExprCast) -> Option<ir::ExprKind> {
        let inner = self.boxed(&c.expr);
        let ty = self.ty(&c.ty);
        Some(ir::ExprKind::Cast { expr: inner?, ty: ty? })
    }

    /// `f(args)`: only named functions; a call of a function of this module is recorded for
    /// the recursion check.
    fn call_expr(&mut self, c: &syn::ExprCall) -> Option<ir::ExprKind> {
        let syn::Expr::Path(p) = &*c.func else {
            self.error(err_at(
                &c.func,
                "only calls of named kernel functions are supported (no closures or function values)",
            ));
            return None;
        };
        let path = self.path(&p.qself, &p.path)?;
        self.check_call_path(&path, &p.path)?;
        let local = match path.as_slice() {
            [name] | [_, name] if path.len() == 1 || path[0] == "self" => Some(name),
            _ => None,
        };
        if let Some(callee) = local.filter(|n| self.local_fns.contains(*n)) {
            if let Some(f) = &self.current_fn {
                self.calls.entry(f.clone()).or_default().push((callee.clone(), p.path.span()));
            }
        }
        let args = self.exprs(c.args.iter())?;
        Some(ir::ExprKind::Call { path, args })
    }

    /// `receiver.method(args)`: only the built-in methods, the compute-only ones in compute
    /// kernels only.
    fn method_call_expr(&mut self, m: &syn::ExprMethodCall) -> Option<ir::ExprKind> {
        if let Some(t) = &m.turbofish {
            self.error(err_at(&t, "turbofish is not supported in kernels"));
            return None;
        }
        let method = m.method.to_string();
        if !ir::SUPPORTED_METHODS.contains(&method.as_str()) {
            self.error(err_at(&m.method, unsupported_method_message(&method)));
            return None;
        }
        if ir::COMPUTE_METHODS.contains(&method.as_str()) && !self.compute {
            self.error(err_at(&m.method, crate::needs_compute(&format!("`{method}`"))));
            return None;
        }
        let receiver = self.boxed(&m.receiver);
        let args = self.exprs(m.args.iter());
        Some(ir::ExprKind::MethodCall { receiver: receiver?, method, args: args? })
    }

    /// `base.field` (named fields only).
    fn field_expr(&mut self, f: &syn::ExprField) -> Option<ir::ExprKind> {
        match &f.member {
            syn::Member::Named(name) => {
                Some(ir::ExprKind::Field { base: self.boxed(&f.base)?, field: name.to_string() })
            }
            syn::Member::Unnamed(_) => {
                self.error(err_at(
                    &f.member,
                    "tuple fields are not supported in kernels: use a struct with named fields",
                ));
                None
            }
        }
    }

    /// `base[index]`.
    fn index_expr(&mut self, i: &syn::ExprIndex) -> Option<ir::ExprKind> {
        let base = self.boxed(&i.expr);
        let index = self.boxed(&i.index);
        Some(ir::ExprKind::Index { base: base?, index: index? })
    }

    /// `Name { field: value, .. }` with every field listed.
    fn struct_expr(&mut self, s: &syn::ExprStruct) -> Option<ir::ExprKind> {
        if let Some(dot2) = &s.dot2_token {
            let rest = &s.rest;
            self.error(err_at(
                &quote!(#dot2 #rest),
                "struct update syntax (`..base`) is not supported in kernels: list every field",
            ));
            return None;
        }
        let name = s.path.segments.last().map(|s| s.ident.to_string())?;
        let mut fields = Vec::new();
        for fv in &s.fields {
            let syn::Member::Named(fname) = &fv.member else {
                self.error(err_at(&fv.member, "use named fields"));
                return None;
            };
            fields.push((fname.to_string(), self.expr(&fv.expr)?));
        }
        Some(ir::ExprKind::StructLit { name, fields })
    }

    /// `[value; len]`.
    fn repeat_expr(&mut self, r: &syn::ExprRepeat) -> Option<ir::ExprKind> {
        let value = self.boxed(&r.expr)?;
        let len = self.array_len(&r.len)?;
        Some(ir::ExprKind::ArrayRepeat { value, len })
    }

    /// `&x` and `&mut x`.
    fn reference_expr(&mut self, r: &syn::ExprReference) -> Option<ir::ExprKind> {
        let inner = self.boxed(&r.expr)?;
        Some(if r.mutability.is_some() { ir::ExprKind::AddrOfMut(inner) } else { ir::ExprKind::AddrOf(inner) })
    }

    /// `if cond { .. } else ..` (no `if let`).
    fn if_expr(&mut self, i: &syn::ExprIf) -> Option<ir::ExprKind> {
        if let syn::Expr::Let(l) = &*i.cond {
            self.error(err_at(
                l,
                "`if let` is not supported in kernels: there are no enums or options; test a value with `if`",
            ));
            return None;
        }
        let cond = self.boxed(&i.cond);
        let then = self.block(&i.then_branch);
        let otherwise = match &i.else_branch {
            None => None,
            Some((_, e)) => Some(self.boxed(e)?),
        };
        Some(ir::ExprKind::If { cond: cond?, then: then?, otherwise })
    }

    /// `{ .. }` (unlabelled).
    fn block_expr(&mut self, b: &syn::ExprBlock) -> Option<ir::ExprKind> {
        if let Some(l) = &b.label {
            self.error(err_at(&l, "labelled blocks are not supported in kernels"));
            return None;
        }
        Some(ir::ExprKind::Block(self.block(&b.block)?))
    }

    /// `while cond { .. }` (no `while let`, no label).
    fn while_expr(&mut self, w: &syn::ExprWhile) -> Option<ir::ExprKind> {
        self.no_label(&w.label)?;
        if let syn::Expr::Let(l) = &*w.cond {
            self.error(err_at(l, "`while let` is not supported in kernels: use `while` with a condition"));
            return None;
        }
        let cond = self.boxed(&w.cond);
        let body = self.block(&w.body);
        Some(ir::ExprKind::While { cond: cond?, body: body? })
    }

    /// `loop { .. }` (no label).
    fn loop_expr(&mut self, l: &syn::ExprLoop) -> Option<ir::ExprKind> {
        self.no_label(&l.label)?;
        Some(ir::ExprKind::Loop { body: self.block(&l.body)? })
    }

    /// `for i in a..b { .. }` and `for i in a..=b { .. }`: the only `for` loops, over an integer
    /// range with both ends.
    fn for_range_expr(&mut self, f: &syn::ExprForLoop) -> Option<ir::ExprKind> {
        self.no_label(&f.label)?;
        let var = match &*f.pat {
            syn::Pat::Ident(pi) if pi.mutability.is_none() && pi.by_ref.is_none() => pi.ident.to_string(),
            other => {
                self.error(err_at(&other, "the loop variable must be a plain name: `for i in 0..n`"));
                return None;
            }
        };
        let range = match &*f.expr {
            syn::Expr::Range(r) => Some(r),
            syn::Expr::Paren(p) => match &*p.expr {
                syn::Expr::Range(r) => Some(r),
                _ => None,
            },
            _ => None,
        };
        let Some(syn::ExprRange { start: Some(start), end: Some(end), limits, .. }) = range else {
            self.error(err_at(
                &f.expr,
                "`for` loops run over an integer range with both ends: `for i in 0..n` or `for i in 0..=n` (iterators are not supported)",
            ));
            return None;
        };
        let start = self.boxed(start);
        let end = self.boxed(end);
        let body = self.block(&f.body);
        Some(ir::ExprKind::ForRange {
            var,
            start: start?,
            end: end?,
            inclusive: matches!(limits, syn::RangeLimits::Closed(_)),
            body: body?,
        })
    }

    /// `break` (no label, no value).
    fn break_expr(&mut self, b: &syn::ExprBreak) -> Option<ir::ExprKind> {
        self.no_label(&b.label.as_ref().map(|l| syn::Label { name: l.clone(), colon_token: Default::default() }))?;
        if let Some(v) = &b.expr {
            self.error(err_at(
                &v,
                "`break` with a value is not supported in kernels: assign to a variable before `break`",
            ));
            return None;
        }
        Some(ir::ExprKind::Break)
    }

    /// `continue` (no label).
    fn continue_expr(&mut self, c: &syn::ExprContinue) -> Option<ir::ExprKind> {
        if let Some(l) = &c.label {
            self.error(err_at(&l, "labelled `continue` is not supported in kernels: use a flag variable"));
            return None;
        }
        Some(ir::ExprKind::Continue)
    }

    /// Reports an expression form the DSL does not support, with what to write instead where
    /// there is a kernel equivalent.
    fn report_unsupported_expr(&mut self, e: &syn::Expr) {
        let error = match e {
            syn::Expr::Closure(c) => err_at(c, "closures are not supported in kernels: write a kernel `fn`"),
            syn::Expr::Tuple(t) => {
                err_at(&t, "tuples are not supported in kernels: declare a struct with named fields")
            }
            syn::Expr::Macro(m) => err_at(&m.mac.path, macro_message(&m.mac)),
            syn::Expr::Try(t) => err(
                t.question_token.span,
                "`?` is not supported in kernels (there are no Results on a GPU): test the value with `if` and `return` early",
            ),
            syn::Expr::Range(r) => err_at(&r, "ranges are only supported as the range of a `for` loop"),
            syn::Expr::Unsafe(u) => err(u.unsafe_token.span, "`unsafe` is not supported in kernels"),
            syn::Expr::Let(l) => err_at(l, "`let` expressions are not supported in kernels: test values with `if`"),
            other => err_at(&other, "this expression is not supported in kernels"),
        };
        self.error(error);
    }

    pub(crate) fn exprs<'a>(&mut self, es: impl Iterator<Item = &'a syn::Expr>) -> Option<Vec<ir::Expr>> {
        let lowered: Vec<Option<ir::Expr>> = es.map(|e| self.expr(e)).collect();
        lowered.into_iter().collect()
    }

    pub(crate) fn no_label(&mut self, l: &Option<syn::Label>) -> Option<()> {
        if let Some(l) = l {
            self.error(err_at(&l.name, "labelled loops are not supported in kernels: use a flag variable"));
            return None;
        }
        Some(())
    }

    pub(crate) fn match_expr(&mut self, m: &syn::ExprMatch) -> Option<ir::ExprKind> {
        let scrutinee = self.boxed(&m.expr)?;
        let mut arms = Vec::new();
        for arm in &m.arms {
            if let Some((if_token, guard)) = &arm.guard {
                self.error(err_at(
                    &quote!(#if_token #guard),
                    "match guards are not supported in kernels: use `if` inside the arm",
                ));
                return None;
            }
            let mut patterns = Vec::new();
            let mut catch_all = false;
            let cases: Vec<&syn::Pat> = match &arm.pat {
                syn::Pat::Or(o) => o.cases.iter().collect(),
                p => vec![p],
            };
            for p in cases {
                match p {
                    syn::Pat::Wild(_) => catch_all = true,
                    // `-1 =>`: syn keeps the sign in the literal's digits.
                    syn::Pat::Lit(syn::ExprLit { lit: syn::Lit::Int(i), .. }) if i.base10_digits().starts_with('-') => {
                        let positive = syn::LitInt::new(&i.to_string()[1..], i.span());
                        let span = span_of(i.span());
                        let lit = self.lit(&syn::Lit::Int(positive))?;
                        let value = Box::new(ir::Expr { kind: ir::ExprKind::Lit(lit), span });
                        patterns.push(ir::Expr { kind: ir::ExprKind::Unary { op: ir::UnOp::Neg, expr: value }, span })
                    }
                    syn::Pat::Lit(l) if matches!(l.lit, syn::Lit::Int(_)) => {
                        patterns.push(ir::Expr { kind: ir::ExprKind::Lit(self.lit(&l.lit)?), span: span_of(l.span()) })
                    }
                    syn::Pat::Path(p) if p.qself.is_none() && p.path.segments.len() == 1 => patterns.push(ir::Expr {
                        kind: ir::ExprKind::Path(vec![p.path.segments[0].ident.to_string()]),
                        span: span_of(p.span()),
                    }),
                    // A bare identifier is a constant pattern when it names a constant (what
                    // rustc decides from scope); otherwise it would bind a new variable.
                    syn::Pat::Ident(pi)
                        if pi.by_ref.is_none()
                            && pi.mutability.is_none()
                            && pi.subpat.is_none()
                            && (self.pattern_consts.contains(&pi.ident.to_string())
                                || is_screaming_case(&pi.ident.to_string())) =>
                    {
                        patterns.push(ir::Expr {
                            kind: ir::ExprKind::Path(vec![pi.ident.to_string()]),
                            span: span_of(pi.ident.span()),
                        })
                    }
                    syn::Pat::Ident(pi) if pi.subpat.is_none() => {
                        self.error(err_at(
                            &pi.ident,
                            format!(
                                "`{}` would bind a variable: `match` in kernels only takes integer literal or `const` patterns; write `_` and use the matched value itself",
                                pi.ident
                            ),
                        ));
                        return None;
                    }
                    other => {
                        self.error(err_at(
                            &other,
                            "`match` in kernels only takes integer literal or `const` patterns and `_`: use `if` for anything else",
                        ));
                        return None;
                    }
                }
            }
            if catch_all {
                // `3 | _` matches everything: an arm without patterns is the IR's `_`.
                patterns.clear();
            }
            let body = self.expr(&arm.body)?;
            arms.push(ir::MatchArm { patterns, body });
        }
        Some(ir::ExprKind::Match { scrutinee, arms })
    }

    pub(crate) fn lit(&mut self, l: &syn::Lit) -> Option<ir::Lit> {
        match l {
            syn::Lit::Int(i) => {
                let suffix = i.suffix();
                if !matches!(suffix, "" | "u32" | "i32" | "usize" | "f32") {
                    self.error(err_at(&i, unsupported_type_message(suffix).unwrap_or("unsupported literal suffix")));
                    return None;
                }
                if suffix == "f32" {
                    let value = i.base10_parse::<f32>().ok()?;
                    return Some(ir::Lit::Float { value, suffix: Some("f32".into()) });
                }
                let Ok(value) = i.base10_parse::<u64>() else {
                    self.error(err_at(&i, "integer literal out of range"));
                    return None;
                };
                let text = i.to_string().replace('_', "");
                let digits = text.strip_suffix(suffix).unwrap_or(&text).to_string();
                Some(ir::Lit::Int { digits, value, suffix: (!suffix.is_empty()).then(|| suffix.to_string()) })
            }
            syn::Lit::Float(f) => {
                let suffix = f.suffix();
                if !matches!(suffix, "" | "f32") {
                    self.error(err_at(
                        &f,
                        "f64 is not supported on GPUs (WebGL2 has no doubles): use f32 (`0.5` or `0.5f32`)",
                    ));
                    return None;
                }
                let value = f.base10_parse::<f32>().ok()?;
                Some(ir::Lit::Float { value, suffix: (!suffix.is_empty()).then(|| suffix.to_string()) })
            }
            syn::Lit::Bool(b) => Some(ir::Lit::Bool(b.value)),
            syn::Lit::Str(_) | syn::Lit::ByteStr(_) | syn::Lit::CStr(_) => {
                self.error(err_at(&l, "strings are not supported in kernels (GPUs have no text): use `u32` codes"));
                None
            }
            syn::Lit::Char(_) | syn::Lit::Byte(_) => {
                self.error(err_at(
                    &l,
                    "characters and bytes are not supported in kernels (GPUs have no text): use `u32` codes",
                ));
                None
            }
            _ => {
                self.error(err_at(&l, "this literal is not supported in kernels"));
                None
            }
        }
    }

    pub(crate) fn path(&mut self, qself: &Option<syn::QSelf>, p: &syn::Path) -> Option<Vec<String>> {
        if qself.is_some() {
            self.error(err_at(&p, "qualified paths are not supported in kernels"));
            return None;
        }
        let mut out = Vec::new();
        for seg in &p.segments {
            if !seg.arguments.is_none() {
                self.error(err_at(&seg.arguments, "generic arguments are not supported here"));
                return None;
            }
            out.push(seg.ident.to_string());
        }
        // `std::f32::consts::PI` and `core::f32::consts::PI` mean `f32::consts::PI`.
        if matches!(out.first().map(String::as_str), Some("std" | "core")) {
            out.remove(0);
        }
        if let Some(first) = out.first() {
            if let Some(msg) = unsupported_type_message(first) {
                self.error(err_at(&p, msg));
                return None;
            }
        }
        Some(out)
    }

    /// Calls through a type path (`Vec3::new`, `f32::max`) must name something the subset
    /// supports; calls through a module path are kernel functions, checked when linking.
    pub(crate) fn check_call_path(&mut self, path: &[String], tokens: &syn::Path) -> Option<()> {
        let written: Vec<String> = tokens.segments.iter().map(|s| s.ident.to_string()).collect();
        let through_type = path.len() == 2 && ir::BUILTIN_TYPES.contains(&path[0].as_str());
        if !through_type {
            let first = written[0].as_str();
            let known_single = written.len() == 1
                && (self.local_fns.contains(first) || self.imported.contains(first) || self.glob_import);
            let module_path = written.len() > 1 && matches!(first, "super" | "crate" | "self");
            if !known_single && !module_path {
                let what = written.join("::");
                let msg = if matches!(first, "std" | "core" | "alloc") || written.len() > 1 {
                    format!("`{what}` is not a kernel function: kernels run on GPUs and can only call kernel functions (of this module, or of another `#[kernel]` module through `super::`/`crate::` or a `use`) and the built-ins of `f32` and glam")
                } else {
                    format!("`{what}` is not a kernel function of this module or one imported from another `#[kernel]` module (`use path::to::module::{what};`): kernels can only call kernel functions and the built-ins of `f32` and glam")
                };
                self.error(err_at(tokens, msg));
                return None;
            }
        }
        if through_type {
            let f = path[1].as_str();
            if ir::COMPUTE_METHODS.contains(&f) {
                self.error(err_at(tokens, format!("call `{f}` as a method: `resources.field.{f}(..)`")));
                return None;
            }
            if !ir::SUPPORTED_METHODS.contains(&f) && !ir::SUPPORTED_CONSTRUCTORS.contains(&f) {
                self.error(err_at(
                    tokens,
                    format!(
                        "`{}::{f}` is not supported in kernels; supported associated functions: {} and the methods {}",
                        path[0],
                        ir::SUPPORTED_CONSTRUCTORS.join(", "),
                        ir::SUPPORTED_METHODS.join(", ")
                    ),
                ));
                return None;
            }
        }
        Some(())
    }
}

/// Loops and blocks without a value stay statements even when they end a block.
pub(crate) fn is_statement_like(e: &ir::Expr) -> bool {
    matches!(
        e.kind,
        ir::ExprKind::While { .. }
            | ir::ExprKind::Loop { .. }
            | ir::ExprKind::ForRange { .. }
            | ir::ExprKind::Assign { .. }
            | ir::ExprKind::Return(_)
            | ir::ExprKind::Break
            | ir::ExprKind::Continue
    )
}

pub(crate) fn is_int_literal(e: &syn::Expr) -> bool {
    match e {
        syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Int(_), .. }) => true,
        syn::Expr::Paren(p) => is_int_literal(&p.expr),
        syn::Expr::Group(g) => is_int_literal(&g.expr),
        _ => false,
    }
}

pub(crate) fn bin_op(op: &syn::BinOp) -> Option<(ir::BinOp, bool)> {
    use ir::BinOp as B;
    use syn::BinOp as S;
    Some(match op {
        S::Add(_) => (B::Add, false),
        S::Sub(_) => (B::Sub, false),
        S::Mul(_) => (B::Mul, false),
        S::Div(_) => (B::Div, false),
        S::Rem(_) => (B::Rem, false),
        S::And(_) => (B::And, false),
        S::Or(_) => (B::Or, false),
        S::BitXor(_) => (B::BitXor, false),
        S::BitAnd(_) => (B::BitAnd, false),
        S::BitOr(_) => (B::BitOr, false),
        S::Shl(_) => (B::Shl, false),
        S::Shr(_) => (B::Shr, false),
        S::Eq(_) => (B::Eq, false),
        S::Lt(_) => (B::Lt, false),
        S::Le(_) => (B::Le, false),
        S::Ne(_) => (B::Ne, false),
        S::Ge(_) => (B::Ge, false),
        S::Gt(_) => (B::Gt, false),
        S::AddAssign(_) => (B::Add, true),
        S::SubAssign(_) => (B::Sub, true),
        S::MulAssign(_) => (B::Mul, true),
        S::DivAssign(_) => (B::Div, true),
        S::RemAssign(_) => (B::Rem, true),
        S::BitXorAssign(_) => (B::BitXor, true),
        S::BitAndAssign(_) => (B::BitAnd, true),
        S::BitOrAssign(_) => (B::BitOr, true),
        S::ShlAssign(_) => (B::Shl, true),
        S::ShrAssign(_) => (B::Shr, true),
        _ => return None,
    })
}

/// What to write instead of a macro, by the macro's name.
pub(crate) fn macro_message(mac: &syn::Macro) -> String {
    let name = mac.path.segments.last().map(|s| s.ident.to_string()).unwrap_or_default();
    match name.as_str() {
        "panic" | "unreachable" | "todo" | "unimplemented" => format!(
            "`{name}!` is not supported in kernels (a GPU cannot panic): return a value that marks the case, e.g. a miss"
        ),
        "assert" | "assert_eq" | "assert_ne" | "debug_assert" | "debug_assert_eq" | "debug_assert_ne" => format!(
            "`{name}!` is not supported in kernels (a GPU cannot panic): check the condition in a CPU test of the kernel instead"
        ),
        "print" | "println" | "eprint" | "eprintln" | "dbg" | "format" | "write" | "writeln" => format!(
            "`{name}!` is not supported in kernels (a GPU cannot print): inspect values in a CPU test of the kernel instead"
        ),
        "vec" => "`vec!` is not supported in kernels (no heap on a GPU): use an array `[x; N]`".to_string(),
        "macro_rules" => "macro definitions are not supported in kernels: write a kernel `fn`".to_string(),
        _ => format!("macros are not supported in kernels (`{name}!`): write the code out, or a kernel `fn`"),
    }
}

pub(crate) fn unsupported_method_message(method: &str) -> String {
    match method {
        "unwrap" | "expect" => format!(
            "`{method}` can panic, and kernels cannot (there are no Options on a GPU): compute the value directly, or test it with `if`"
        ),
        "iter" | "into_iter" | "map" | "sum" | "fold" | "collect" => {
            format!("iterators are not supported in kernels (`{method}`): write a `for i in 0..n` loop")
        }
        "clone" => "`clone` is not needed: kernel values are Copy".to_string(),
        _ => format!(
            "method `{method}` is not supported in kernels; supported methods: {}",
            ir::SUPPORTED_METHODS.join(", ")
        ),
    }
}
