//! Typing calls: kernel functions, builtins (glam constructors and free functions), methods
//! of glam types and the DSL's runtime types, and field access; and the refusal of `&mut` of a
//! field or element as an argument.

use super::Cx;
use crate::ir::{self, Expr, ExprKind as K, Span};
use crate::types::{self, Ty, F32, I32, U32};
use crate::CodegenError;

impl Cx<'_> {
    fn args(&mut self, args: &[Expr]) -> Result<Vec<Ty>, CodegenError> {
        let mut out = Vec::new();
        for a in args {
            let t = self.expr(a)?;
            out.push(self.shallow(&t));
        }
        Ok(out)
    }

    pub(super) fn call(&mut self, path: &[String], args: &[Expr], span: Span) -> Result<Ty, CodegenError> {
        if let Some(name) = self.program.kernel_fn_of_path(path) {
            let callee = self.program.fns[name].item.clone();
            if callee.params.len() != args.len() {
                return Err(self.error(span, format!("`{name}` takes {} arguments", callee.params.len())));
            }
            for (p, a) in callee.params.iter().zip(args) {
                if let Some(message) = partial_place_argument(a) {
                    return Err(self.error(a.span, message));
                }
                let pt = self.resolve_type(&p.ty, p.span)?;
                let at = self.expr(a)?;
                self.unify(&pt, &at, a.span)?;
            }
            return match &callee.ret {
                Some(t) => self.resolve_type(t, span),
                None => Ok(Ty::Unit),
            };
        }
        if path.len() == 2 {
            let (ty_name, f) = (path[0].as_str(), path[1].as_str());
            if let Some(t) = Ty::builtin(ty_name) {
                match (f, &t) {
                    ("new", Ty::Vector(s, n)) => {
                        let at = self.args(args)?;
                        let mut comps = 0u8;
                        for (a, arg) in at.iter().zip(args) {
                            match a {
                                Ty::Vector(s2, m) if s2 == s => comps += m,
                                _ => {
                                    self.unify(a, &Ty::Scalar(*s), arg.span)?;
                                    comps += 1;
                                }
                            }
                        }
                        if comps != *n {
                            return Err(self.error(span, format!("`{ty_name}::new` takes {n} components")));
                        }
                        return Ok(t);
                    }
                    ("splat", Ty::Vector(s, _)) => {
                        let at = self.args(args)?;
                        if at.len() != 1 {
                            return Err(self.error(span, "`splat` takes one argument"));
                        }
                        self.unify(&at[0], &Ty::Scalar(*s), span)?;
                        return Ok(t);
                    }
                    ("from_bits", _) if t == F32 => {
                        let at = self.args(args)?;
                        if at.len() != 1 {
                            return Err(self.error(span, "`f32::from_bits` takes one argument"));
                        }
                        self.unify(&at[0], &U32, span)?;
                        return Ok(F32);
                    }
                    _ if !args.is_empty() => {
                        // `f32::max(a, b)`, `Vec3::dot(a, b)`: a method call written as a path.
                        let recv = self.expr(&args[0])?;
                        let recv = self.shallow(&recv).strip_ref().clone();
                        let recv = if recv.is_int() && matches!(t, Ty::Scalar(_)) {
                            self.unify(&recv, &t, span)?
                        } else {
                            recv
                        };
                        return self.method(&recv, f, &args[1..], span);
                    }
                    _ => {}
                }
            }
        }
        Err(self.error(
            span,
            format!(
                "`{}` is not a kernel function or a supported built-in (kernels can only call kernel functions)",
                path.join("::")
            ),
        ))
    }

    pub(super) fn method(&mut self, recv: &Ty, method: &str, args: &[Expr], span: Span) -> Result<Ty, CodegenError> {
        let at = self.args(args)?;
        // Arguments of integer methods take the receiver's type (`x.wrapping_add(1)`), except
        // shift amounts, which are u32 in Rust.
        let recv = self.shallow(recv);
        match method {
            "wrapping_shl" | "wrapping_shr" => {
                if let Some(a) = at.first() {
                    self.unify(a, &U32, span)?;
                }
            }
            "fetch" | "load" | "atomic_load" => {
                if let Some(a) = at.first() {
                    self.unify(a, &U32, span)?;
                }
            }
            "store" => {
                if let (Some(i), Some(v), Ty::Storage(elem)) = (at.first(), at.get(1), &recv) {
                    self.unify(i, &U32, span)?;
                    self.unify(v, elem, span)?;
                }
            }
            "atomic_add" | "atomic_sub" | "atomic_min" | "atomic_max" | "atomic_exchange" | "atomic_store" => {
                for a in &at {
                    self.unify(a, &U32, span)?;
                }
            }
            "extend" | "lerp" | "powf" | "atan2" | "clamp" | "min" | "max" | "dot" | "cross" | "distance"
            | "reflect" | "wrapping_add" | "wrapping_sub" | "wrapping_mul" => {
                let s = recv.scalar().map(Ty::Scalar);
                for (i, a) in at.iter().enumerate() {
                    let want = match (method, i) {
                        ("extend", _) | ("lerp", 1) => s.clone(),
                        _ if recv.is_int() => Some(recv.clone()),
                        _ => None,
                    };
                    match want {
                        Some(w) => {
                            self.unify(a, &w, span)?;
                        }
                        None if a.is_int() => {
                            self.unify(a, &recv, span)?;
                        }
                        None => {}
                    }
                }
            }
            _ => {}
        }
        let at: Vec<Ty> = at.iter().map(|t| self.shallow(t)).collect();
        let recv_c = if let Ty::IntVar(_) = recv { I32 } else { recv.clone() };
        match types::method_result(&recv_c, method, &at) {
            Some(t) if recv.is_int() && t == recv_c => Ok(recv),
            Some(t) => Ok(t),
            None => Err(self.error(span, format!("`{recv}` has no method `{method}` in the kernel subset"))),
        }
    }

    pub(super) fn field(&mut self, base: &Ty, field: &str, span: Span) -> Result<Ty, CodegenError> {
        match base {
            Ty::Vector(s, n) => {
                let idx = match field {
                    "x" => 0,
                    "y" => 1,
                    "z" => 2,
                    "w" => 3,
                    _ => 99,
                };
                if idx >= *n {
                    return Err(self.error(span, format!("`{base}` has no field `{field}`")));
                }
                Ok(Ty::Scalar(*s))
            }
            Ty::Struct(name) | Ty::Resource(name) => {
                let def = &self.program.structs[name].item;
                match def.fields.iter().find(|f| f.name == field) {
                    Some(f) => {
                        let t = f.ty.clone();
                        self.resolve_type(&t, span)
                    }
                    None => Err(self.error(span, format!("`{name}` has no field `{field}`"))),
                }
            }
            other => Err(self.error(span, format!("`{other}` has no fields"))),
        }
    }
}

/// `&mut place` as a kernel function's argument, where `place` is a field or an array element:
/// the message refusing it. WGSL (without the `unrestricted_pointer_parameters` extension)
/// takes only the address of a whole variable as a pointer argument; naga's SPIR-V writer
/// panics on anything else (gfx-rs/wgpu #4540, #6875) and Chromium's Tint rejects it. The DSL
/// means one thing on every target, so it is refused for all of them.
fn partial_place_argument(arg: &Expr) -> Option<String> {
    let K::AddrOfMut(place) = &unparen(arg).kind else { return None };
    let what = match &unparen(place).kind {
        K::Field { .. } => "a field",
        K::Index { .. } => "an array element",
        _ => return None,
    };
    let text = place_text(place).unwrap_or_else(|| "place".to_string());
    let local = match &unparen(place).kind {
        K::Field { field, .. } => field.clone(),
        _ => "element".to_string(),
    };
    Some(format!(
        "`&mut {text}` passes a pointer to {what}: WGSL takes only the address of a whole variable as a function's pointer argument. Copy it into a local, pass `&mut local`, and write it back: `let mut {local} = {text}; f(.., &mut {local}, ..); {text} = {local};`"
    ))
}

fn unparen(e: &Expr) -> &Expr {
    match &e.kind {
        K::Paren(inner) => unparen(inner),
        _ => e,
    }
}

/// A place expression as the kernel source spells it (`path.rng`, `a[i]`, `(*p).x`), for
/// messages; `None` for anything more complex.
fn place_text(e: &Expr) -> Option<String> {
    Some(match &e.kind {
        K::Path(p) => p.join("::"),
        K::Paren(inner) => format!("({})", place_text(inner)?),
        K::Unary { op: ir::UnOp::Deref, expr } => format!("*{}", place_text(expr)?),
        K::Field { base, field } => format!("{}.{field}", place_text(base)?),
        K::Index { base, index } => {
            let i = match &index.kind {
                K::Lit(ir::Lit::Int { value, .. }) => value.to_string(),
                _ => place_text(index).unwrap_or_else(|| "..".to_string()),
            };
            format!("{}[{i}]", place_text(base)?)
        }
        _ => return None,
    })
}
