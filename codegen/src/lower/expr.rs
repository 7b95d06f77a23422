//! Expressions: each returns its text and precedence. Where a language's operator, built-in or
//! conversion means something else than Rust's, the expression goes through a helper
//! (`lp_*`) or a spelling the [`crate::language::Language`] provides.

use super::{float_lit, has_effects, helper_suffix, is_zero_literal, op_prec, strip_parens, Lowerer, R};
use crate::infer;
use crate::ir::{self, BinOp, Expr, ExprKind as K, UnOp};
use crate::language::{prec, prec::wrap, AtomicOp, Bitcast, Fetch, Helper, StorageElement, Text};
use crate::names;
use crate::types::{self, ConstValue, Scalar, Ty, F32, U32};

impl<'a> Lowerer<'a> {
    /// An assignable place: a variable, `*param`, a field or an element.
    pub(super) fn place(&mut self, e: &Expr) -> R<String> {
        Ok(self.expr(e)?.0)
    }

    pub(super) fn expr(&mut self, e: &Expr) -> R<Text> {
        let span = e.span;
        Ok(match &e.kind {
            K::Lit(l) => (self.literal(l, self.types.ty(e).clone()), prec::ATOM),
            K::Paren(inner) => self.expr(inner)?,
            K::Path(path) => self.path(e, path)?,
            K::Unary { op, expr } => {
                let inner = self.expr(expr)?;
                let t = self.types.ty(expr).clone();
                match op {
                    UnOp::Deref => self.lang.deref(inner),
                    UnOp::Neg => (format!("-{}", wrap(inner, prec::ATOM)), prec::UNARY),
                    UnOp::Not if t.scalar() == Some(Scalar::Bool) => {
                        (format!("!{}", wrap(inner, prec::ATOM)), prec::UNARY)
                    }
                    UnOp::Not => (format!("~{}", wrap(inner, prec::ATOM)), prec::UNARY),
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
                    return self.resource_field(res, field, span);
                }
                let b = self.expr(base)?;
                let b = self.auto_deref(b, &bt);
                (format!("{}.{}", wrap(b, prec::ATOM), names::safe(field)), prec::ATOM)
            }
            K::Index { base, index } => {
                let bt = self.types.ty(base).clone();
                let b = self.expr(base)?;
                let b = self.auto_deref(b, &bt);
                let i = self.expr(index)?;
                (format!("{}[{}]", wrap(b, prec::ATOM), i.0), prec::ATOM)
            }
            K::Cast { expr, .. } => {
                let from = self.types.ty(expr).clone();
                let to = self.types.ty(e).clone();
                self.cast(expr, &from, &to)?
            }
            K::StructLit { name, fields } => self.struct_lit(span, name, fields)?,
            K::Array(elems) => {
                let t = self.types.ty(e).clone();
                let tn = self.ty_name(&t);
                let mut vals = Vec::new();
                for el in elems {
                    vals.push(self.expr(el)?.0);
                }
                (format!("{tn}({})", vals.join(", ")), prec::ATOM)
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
                match self.lang.zero_value(&tn).filter(|_| is_zero_literal(value)) {
                    Some(zero) => (zero, prec::ATOM),
                    None => {
                        let v = self.expr(value)?.0;
                        (format!("{tn}({})", vec![v; n as usize].join(", ")), prec::ATOM)
                    }
                }
            }
            K::AddrOfMut(place) => {
                let pt = self.types.ty(place).clone();
                let p = self.expr(place)?;
                if let Ty::RefMut(_) = pt {
                    // `&mut *param` or passing a `&mut` parameter on.
                    return Ok(p);
                }
                self.lang.address_of(p)
            }
            K::AddrOf(inner) => self.expr(inner)?,
            K::If { cond, then, otherwise } if self.const_bool(cond).is_some() => {
                match (self.const_bool(cond), then.tail.as_deref(), otherwise.as_deref()) {
                    (Some(true), Some(t), _) if then.stmts.is_empty() => self.expr(t)?,
                    (Some(false), _, Some(o)) => self.expr(o)?,
                    _ => return Err(self.error(span, "bind this `if` to a `let` first")),
                }
            }
            K::If { cond, then, otherwise } => self.if_expr(e, cond, then, otherwise.as_deref())?,
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

    fn struct_lit(&mut self, span: ir::Span, name: &str, fields: &[(String, Expr)]) -> R<Text> {
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
        self.structs_used.insert(name.to_string());
        Ok((format!("{}({})", names::safe(name), vals.join(", ")), prec::ATOM))
    }

    /// An `if` with a value, as an expression (`?:`, `select`).
    fn if_expr(&mut self, e: &Expr, cond: &Expr, then: &ir::Block, otherwise: Option<&Expr>) -> R<Text> {
        let span = e.span;
        let (Some(t), Some(o)) = (then.tail.as_ref(), otherwise) else {
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
        Ok(self.lang.select(c, a, b))
    }

    /// Rust dereferences `&mut` automatically for fields, indexing and methods; some languages
    /// do not.
    fn auto_deref(&self, v: Text, t: &Ty) -> Text {
        if matches!(t, Ty::RefMut(_)) {
            self.lang.auto_deref(v)
        } else {
            v
        }
    }

    /// A scalar or vector field of a resource struct (a texel array is only read through
    /// [`fetch`](Self::fetch)).
    fn resource_field(&mut self, res: &str, field: &str, span: ir::Span) -> R<Text> {
        if let Some(v) = self.specialized(res, field) {
            return Ok((format!("{v}u"), prec::ATOM));
        }
        let def = &self.program.structs[res].item;
        let array = def.fields.iter().find_map(|f| match &f.ty {
            ir::Type::Named { name, .. } if f.name == field => Some(name.as_str()),
            _ => None,
        });
        match array {
            Some("Texels") => return Err(self.error(span, "read texels as `resources.field.fetch(index)`")),
            Some("Storage") => {
                return Err(self.error(
                    span,
                    "use storage as `resources.field.load(index)` and `resources.field.store(index, value);`",
                ))
            }
            Some("Atomics") => {
                return Err(
                    self.error(span, "use atomics through their methods: `resources.field.atomic_add(index, value)`")
                )
            }
            _ => {}
        }
        self.resources_used.insert((res.to_string(), field.to_string()));
        Ok((self.lang.resource_field(&super::snake(res), field), prec::ATOM))
    }

    pub(super) fn literal(&mut self, l: &ir::Lit, ty: Ty) -> String {
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
                self.lang.int_literal(&digits, matches!(ty, Ty::Scalar(Scalar::U32 | Scalar::USize)))
            }
        }
    }

    pub(super) fn const_value(&mut self, t: &Ty, v: &ConstValue) -> String {
        match v {
            ConstValue::F32(f) if f.is_nan() => self.bits_to_float(0x7fc0_0000),
            ConstValue::F32(f) if *f == f32::INFINITY => self.bits_to_float(0x7f80_0000),
            ConstValue::F32(f) if *f == f32::NEG_INFINITY => self.bits_to_float(0xff80_0000),
            ConstValue::F32(f) => float_lit(*f),
            ConstValue::U32(u) => format!("{u}u"),
            ConstValue::I32(i) if *i == i32::MIN => "(-2147483647 - 1)".into(),
            ConstValue::I32(i) => self.lang.int_literal(&i.to_string(), false),
            ConstValue::Vector(comps) => {
                let tn = self.ty_name(t);
                let s = t.scalar().unwrap_or(Scalar::F32);
                let all_same = comps.windows(2).all(|w| w[0] == w[1]);
                let lang = self.lang;
                let comp = |c: f64| match s {
                    Scalar::F32 => float_lit(c as f32),
                    Scalar::U32 => format!("{}u", c as u32),
                    _ => lang.int_literal(&format!("{}", c as i32), false),
                };
                if all_same {
                    format!("{tn}({})", comp(comps[0]))
                } else {
                    format!("{tn}({})", comps.iter().map(|c| comp(*c)).collect::<Vec<_>>().join(", "))
                }
            }
        }
    }

    /// NaN and infinities have no literal in some languages, and others reject them in
    /// constant expressions: build them from bits (see [`Language::float_from_bits`]).
    fn bits_to_float(&mut self, bits: u32) -> String {
        self.lang.float_from_bits(bits, &mut self.helpers)
    }

    fn path(&mut self, e: &Expr, path: &[String]) -> R<Text> {
        if let Some(id) = self.types.uses.get(&infer::key(e)) {
            let b = &self.types.bindings[*id];
            return Ok((b.out_name.clone(), prec::ATOM));
        }
        let name = path.last().expect("non-empty path");
        if (path.len() == 1 || types::assoc_const(path).is_none()) && self.program.consts.contains_key(name) {
            self.consts_used.insert(name.clone());
            return Ok((names::safe(name), prec::ATOM));
        }
        match types::assoc_const(path) {
            Some((t, v)) => {
                let s = self.const_value(&t, &v);
                let p = if s.starts_with('-') || s.starts_with('(') { prec::UNARY } else { prec::ATOM };
                Ok((s, p))
            }
            None => Err(self.error(e.span, format!("`{}` is not supported in kernels", path.join("::")))),
        }
    }

    pub(super) fn binary_text(&mut self, op: BinOp, l: Text, lt: &Ty, r: Text, rt: &Ty, span: ir::Span) -> R<Text> {
        let p = op_prec(op);
        let lt = lt.strip_ref();
        // Semantics that differ between languages.
        match self.lang.binary(op, &l, lt, &r, rt, &mut self.helpers) {
            Ok(Some(text)) => return Ok(text),
            Ok(None) => {}
            Err(message) => return Err(self.error(span, message)),
        }
        let (lmin, rmin) = match op {
            // WGSL: bitwise operands are unary expressions (same-operator chains excepted);
            // shifts take unary operands on both sides.
            BinOp::BitAnd | BinOp::BitOr | BinOp::BitXor => (if l.1 == p { p } else { prec::UNARY }, prec::UNARY),
            BinOp::Shl | BinOp::Shr => (prec::UNARY, prec::UNARY),
            BinOp::And | BinOp::Or => (if l.1 == p { p } else { prec::REL }, prec::REL),
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => (prec::SHIFT, prec::SHIFT),
            _ => (p, p + 1),
        };
        let r = self.shift_amount(op, r, rt);
        Ok((format!("{} {} {}", wrap(l, lmin), op.symbol(), wrap(r, rmin)), p))
    }

    /// The DSL only allows literal amounts for `<<`/`>>`; the language spells them.
    pub(super) fn shift_amount(&self, op: BinOp, r: Text, rt: &Ty) -> Text {
        match op {
            BinOp::Shl | BinOp::Shr => self.lang.shift_amount(r, rt),
            _ => r,
        }
    }

    fn cast(&mut self, inner: &Expr, from: &Ty, to: &Ty) -> R<Text> {
        use Scalar::*;
        let (Some(f), Some(t)) = (from.scalar(), to.scalar()) else {
            return Err(self.error(inner.span, "unsupported cast"));
        };
        let v = self.expr(inner)?;
        let same = |a: Scalar| if a == USize { U32 } else { a };
        let conv = |name: &str| (format!("{name}({})", v.0), prec::ATOM);
        let lang = self.lang;
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
            (I32, U32) => conv(lang.bitcast(Bitcast::I32ToU32)),
            (U32, I32) => conv(lang.bitcast(Bitcast::U32ToI32)),
            (U32, F32) => {
                if fits_in_24_bits(inner) {
                    // Exact in f32: the plain conversion cannot round.
                    conv(lang.scalar_type(F32))
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
            (Bool, I32) => conv(lang.scalar_type(I32)),
            (Bool, U32) => conv(lang.scalar_type(U32)),
            (a, b) => {
                return Err(self.error(
                    inner.span,
                    format!("cast from {} to {} is not supported", types::scalar_rust(a), types::scalar_rust(b)),
                ))
            }
        })
    }

    fn call(&mut self, e: &Expr, path: &[String], args: &[Expr]) -> R<Text> {
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
            return Ok((format!("{}({})", names::safe(name), out.join(", ")), prec::ATOM));
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
                Ok((format!("{tn}({})", vals.join(", ")), prec::ATOM))
            }
            "from_bits" if ty_name == "f32" => {
                let v = self.expr(&args[0])?.0;
                Ok((format!("{}({v})", self.lang.bitcast(Bitcast::U32ToF32)), prec::ATOM))
            }
            _ => self.method(e, &args[0], f, &args[1..]),
        }
    }

    fn method(&mut self, e: &Expr, receiver: &Expr, method: &str, args: &[Expr]) -> R<Text> {
        let rt = self.types.ty(receiver).strip_ref().clone();
        if method == "fetch" {
            return self.fetch(e, receiver, &rt, &args[0]);
        }
        if method == "load" || AtomicOp::of_method(method).is_some() {
            return Ok((self.compute_access(e, receiver, method, args)?, prec::ATOM));
        }
        if method == "store" {
            return Err(
                self.error(e.span, "`store` is a statement: write `resources.field.store(index, value);` on its own")
            );
        }
        let recv = self.expr(receiver)?;
        let recv_t = self.types.ty(receiver).clone();
        let r = self.auto_deref(recv, &recv_t);
        let mut a = Vec::new();
        for x in args {
            a.push(self.expr(x)?);
        }
        let call = |f: &str, r: &Text, a: &[Text]| {
            let mut all = vec![r.0.clone()];
            all.extend(a.iter().map(|x| x.0.clone()));
            (format!("{f}({})", all.join(", ")), prec::ATOM)
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
            "atan2" => call(self.lang.builtin("atan2"), &r, &a),
            "recip" => (format!("1.0 / {}", wrap(r, prec::MUL + 1)), prec::MUL),
            "to_radians" => {
                (format!("{} * {}", wrap(r, prec::MUL), float_lit(std::f32::consts::PI / 180.0)), prec::MUL)
            }
            "to_degrees" => {
                (format!("{} * {}", wrap(r, prec::MUL), float_lit(180.0 / std::f32::consts::PI)), prec::MUL)
            }
            "fract" => {
                let (ty, suffix) = (self.ty_name(&rt), helper_suffix(&rt));
                let name = format!("lp_fract_{suffix}");
                self.helpers.insert(Helper::Fract { ty, suffix });
                call(&name, &r, &a)
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
            "to_bits" => call(self.lang.bitcast(Bitcast::F32ToU32), &r, &a),
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
            "wrapping_add" if int => {
                (format!("{} + {}", wrap(r, prec::ADD), wrap(a[0].clone(), prec::ADD + 1)), prec::ADD)
            }
            "wrapping_sub" if int => {
                (format!("{} - {}", wrap(r, prec::ADD), wrap(a[0].clone(), prec::ADD + 1)), prec::ADD)
            }
            "wrapping_mul" if int => {
                (format!("{} * {}", wrap(r, prec::MUL), wrap(a[0].clone(), prec::MUL + 1)), prec::MUL)
            }
            "wrapping_neg" if rt == U32 => (format!("0u - {}", wrap(r, prec::ADD + 1)), prec::ADD),
            "wrapping_neg" => (format!("-{}", wrap(r, prec::ATOM)), prec::UNARY),
            "wrapping_shl" | "wrapping_shr" => {
                let op = if method == "wrapping_shl" { "<<" } else { ">>" };
                (format!("{} {op} ({} & 31u)", wrap(r, prec::UNARY), wrap(a[0].clone(), prec::UNARY)), prec::SHIFT)
            }
            "length_squared" => {
                let (ty, suffix) = (self.ty_name(&rt), helper_suffix(&rt));
                let name = format!("lp_length_squared_{suffix}");
                self.helpers.insert(Helper::LengthSquared { ty, suffix });
                call(&name, &r, &a)
            }
            "distance" => (format!("length({} - {})", r.0, wrap(a[0].clone(), prec::ADD + 1)), prec::ATOM),
            "min_element" | "max_element" | "element_sum" | "element_product" => {
                let op = match method {
                    "min_element" => "min",
                    "max_element" => "max",
                    "element_sum" => "+",
                    _ => "*",
                };
                let Ty::Vector(scalar, n) = rt else { unreachable!("vector receiver") };
                let (ty, suffix) = (self.ty_name(&rt), helper_suffix(&rt));
                let name = format!("lp_{method}_{suffix}");
                self.helpers.insert(Helper::Reduce { op, ty, n, suffix, scalar });
                call(&name, &r, &a)
            }
            "extend" => {
                let t = self.types.ty(e).clone();
                let ext = self.ty_name(&t);
                (format!("{ext}({}, {})", r.0, a[0].0), prec::ATOM)
            }
            "truncate" => {
                let Ty::Vector(_, n) = rt else { unreachable!("vector receiver") };
                (format!("{}.{}", wrap(r, prec::ATOM), &"xyzw"[..n as usize - 1]), prec::ATOM)
            }
            "xy" | "xz" | "yz" | "xyz" => (format!("{}.{method}", wrap(r, prec::ATOM)), prec::ATOM),
            m if m.starts_with("as_") => {
                let t = self.types.ty(e).clone();
                let target = self.ty_name(&t);
                (format!("{target}({})", r.0), prec::ATOM)
            }
            other => return Err(self.error(e.span, format!("`{other}` is not implemented for `{rt}` in codegen"))),
        })
    }

    /// `resources.field.fetch(index)`.
    fn fetch(&mut self, e: &Expr, receiver: &Expr, rt: &Ty, index: &Expr) -> R<Text> {
        let K::Field { base, field } = &strip_parens(receiver).kind else {
            return Err(self.error(e.span, "read texels as `resources.field.fetch(index)`"));
        };
        let Ty::Resource(res) = self.types.ty(base).strip_ref().clone() else {
            return Err(self.error(e.span, "read texels as `resources.field.fetch(index)`"));
        };
        self.resources_used.insert((res.clone(), field.clone()));
        let i = self.expr(index)?;
        let unsigned = matches!(rt, Ty::Texels(el) if matches!(**el, Ty::Vector(Scalar::U32, _)));
        let fetch = Fetch { unsigned, rows: self.selection.texel_rows };
        Ok((self.lang.fetch(&super::snake(&res), field, i, fetch, &mut self.helpers), prec::ATOM))
    }
}

impl Lowerer<'_> {
    /// `resources.field.load(i)`, `.store(i, v)` (its statement text, ending in `;`) and
    /// `.atomic_*(i, ..)` on a compute module's `Storage` and `Atomics` fields.
    pub(super) fn compute_access(&mut self, e: &Expr, receiver: &Expr, method: &str, args: &[Expr]) -> R<String> {
        let usage = "use storage and atomics as `resources.field.method(..)`";
        let K::Field { base, field } = &strip_parens(receiver).kind else {
            return Err(self.error(e.span, usage));
        };
        let Ty::Resource(res) = self.types.ty(base).strip_ref().clone() else {
            return Err(self.error(e.span, usage));
        };
        self.resources_used.insert((res.clone(), field.clone()));
        let global = super::snake(&res);
        let rt = self.types.ty(receiver).strip_ref().clone();
        let index = self.expr(&args[0])?;
        let value = match args.get(1) {
            Some(v) => Some(self.expr(v)?),
            None => None,
        };
        if let Some(op) = AtomicOp::of_method(method) {
            return self.lang.atomic(&global, field, op, index, value).map_err(|m| self.error(e.span, m));
        }
        let Some(element) = (match &rt {
            Ty::Storage(el) => StorageElement::of(el),
            _ => None,
        }) else {
            return Err(self.error(e.span, format!("`{method}` is for `Storage<..>` fields, not `{rt}`")));
        };
        let place = self.lang.storage_element(&global, field, element, index).map_err(|m| self.error(e.span, m))?;
        Ok(match value {
            Some(v) => format!("{place} = {};", v.0),
            None => place,
        })
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
