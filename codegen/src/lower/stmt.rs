//! Functions and statements, and the decision of what becomes a statement: a block-like value
//! (`if`, `match`, block) is lowered into its destination (`return`, an assignment, nothing)
//! branch by branch, unless it is an `if` simple enough to stay an expression.

use super::{has_effects, is_zero_literal, strip_parens, Lowerer, R};
use crate::infer::{self, BindingKind};
use crate::ir::{self, Expr, ExprKind as K};
use crate::language::prec;
use crate::names;
use crate::types::Ty;
use crate::Located;

/// Where the value of a block-like expression (`if`, `match`, block) goes.
#[derive(Clone)]
pub(super) enum Dest {
    Return,
    Assign(String),
    Discard,
}

impl<'a> Lowerer<'a> {
    pub(super) fn function(&mut self, f: &'a Located<ir::FnDef>) -> R<()> {
        self.func = Some(f);
        self.used_names = self.types.bindings.iter().map(|b| b.out_name.clone()).collect();
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
                    self.note_structs(&t);
                    params.push(self.lang.ref_param(&t, &b.out_name));
                }
                _ if self.lang.param_needs_copy(&b.ty, p.mutable) => {
                    // The parameter cannot be assigned (or indexed dynamically) in this
                    // language: copy it into a variable of the Rust name.
                    let arg = self.fresh(&format!("{}_arg", p.name));
                    params.push(self.decl(&b.ty, &arg));
                    let local = self.local(&b.ty, &b.out_name, true);
                    prologue.push(format!("{local} = {arg};"));
                }
                _ => params.push(self.decl(&b.ty, &b.out_name)),
            }
        }
        let ret = self.types.ret.clone();
        self.note_structs(&ret);
        let header = self.lang.function_head(&names::safe(&def.name), &params, &ret);
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
    pub(super) fn is_block_like(&self, e: &Expr) -> bool {
        let e = strip_parens(e);
        match &e.kind {
            // Decided by specialisation: only the live branch is emitted, so the value is an
            // expression when that branch is one (`let x = if scene.has_f != 0 { a } else { b };`
            // in a variant without `f` is `let x = b;`, the text it had before `f` existed).
            K::If { cond, then, otherwise } if self.const_bool(cond).is_some() => {
                let live = if self.const_bool(cond) == Some(true) {
                    then.tail.as_deref().filter(|_| then.stmts.is_empty())
                } else {
                    otherwise.as_deref().map(strip_parens).and_then(|o| match &o.kind {
                        K::Block(b) if b.stmts.is_empty() => b.tail.as_deref(),
                        K::If { .. } => Some(o),
                        _ => None,
                    })
                };
                live.is_none_or(|x| self.is_block_like(x))
            }
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
                let head = self.lang.if_head(&c.0);
                self.line(&head);
                self.indent += 1;
                self.block_into(then, dest)?;
                self.indent -= 1;
                self.else_chain(otherwise.as_deref().map(strip_parens), dest)?;
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
            // `resources.field.store(i, v)` and `atomic_store`: statements with no value.
            K::MethodCall { receiver, method, args }
                if matches!(dest, Dest::Discard) && (method == "store" || method == "atomic_store") =>
            {
                self.mark(e.span);
                let text = self.compute_access(e, receiver, method, args)?;
                let text = if text.ends_with(';') { text } else { format!("{text};") };
                self.line(&text);
            }
            _ => {
                let ty = self.types.ty(e).clone();
                self.mark(e.span);
                let v = self.expr(e)?.0;
                match dest {
                    Dest::Return => self.line(&format!("return {v};")),
                    Dest::Assign(place) => self.line(&format!("{place} = {v};")),
                    Dest::Discard => {
                        let used = ty != Ty::Unit && !matches!(e.kind, K::Call { .. });
                        let s = self.lang.discard(&v, used);
                        self.line(&s);
                    }
                }
            }
        }
        Ok(())
    }

    /// The `else` branches of an `if` statement: `else if` chains stay flat; an `else` block
    /// is emitted without extra braces.
    fn else_chain(&mut self, mut otherwise: Option<&Expr>, dest: &Dest) -> R<()> {
        while let Some(o) = otherwise {
            match &o.kind {
                // Branches decided by specialisation: skip a dead `else if`, or end the chain at
                // a live one.
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
                    let head = format!("}} else {}", self.lang.if_head(&c));
                    self.line(&head);
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
                let d = self.local(&s_ty, &name, false);
                self.line(&format!("{d} = {v};"));
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
            let head = self.lang.if_head(&conds.join(" || "));
            self.line(&if first { head } else { format!("}} else {head}") });
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
                let d = self.local(&b.ty, &b.out_name, needs_var);
                match init {
                    None => self.line(&format!("{d};")),
                    Some(init) if self.is_block_like(init) => {
                        self.line(&format!("{d};"));
                        self.value_into(init, &Dest::Assign(b.out_name.clone()))?;
                    }
                    Some(init) => {
                        if let K::ArrayRepeat { value, .. } = &strip_parens(init).kind {
                            let Ty::Array(_, n) = b.ty else { unreachable!("array type") };
                            self.line(&format!("{d};"));
                            if !is_zero_literal(value) || !self.lang.locals_start_zeroed() {
                                let v = self.expr(value)?.0;
                                let i = self.fresh("i");
                                let fill = self.lang.fill_array(&b.out_name, n, &i, &v);
                                self.line(&fill);
                            }
                        } else {
                            let v = self.expr(init)?.0;
                            self.line(&format!("{d} = {v};"));
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
        match &e.kind {
            K::If { .. } | K::Match { .. } | K::Block(_) => self.value_into(e, &Dest::Discard),
            K::While { cond, body } => {
                self.mark(e.span);
                let c = self.expr(cond)?.0;
                let head = self.lang.while_head(&c);
                self.line(&head);
                self.loop_body(body)
            }
            K::Loop { body } => {
                self.mark(e.span);
                let head = self.lang.loop_head();
                self.line(&head);
                self.loop_body(body)
            }
            K::ForRange { start, end, inclusive, body, .. } => self.for_range(e, start, end, *inclusive, body),
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
            K::Assign { op, place, value } => self.assign(e, *op, place, value),
            _ => self.value_into(e, &Dest::Discard),
        }
    }

    /// A loop's body and its closing brace.
    fn loop_body(&mut self, body: &ir::Block) -> R<()> {
        self.indent += 1;
        self.block_into(body, &Dest::Discard)?;
        self.indent -= 1;
        self.line("}");
        Ok(())
    }

    fn for_range(&mut self, e: &Expr, start: &Expr, end: &Expr, inclusive: bool, body: &ir::Block) -> R<()> {
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
            let d = self.local(&b.ty, &name, false);
            self.line(&format!("{d} = {v};"));
            name
        };
        let cmp = if inclusive { "<=" } else { "<" };
        let head = self.lang.for_range_head(&b.out_name, &tn, &s, cmp, &en);
        self.line(&head);
        self.loop_body(body)
    }

    fn assign(&mut self, e: &Expr, op: Option<ir::BinOp>, place: &Expr, value: &Expr) -> R<()> {
        self.mark(e.span);
        let p = self.place(place)?;
        if self.is_block_like(value) {
            if let Some(op) = op {
                let t = self.types.ty(value).clone();
                let tmp = self.fresh("value");
                let d = self.local(&t, &tmp, true);
                self.line(&format!("{d};"));
                self.value_into(value, &Dest::Assign(tmp.clone()))?;
                let pt = self.types.ty(place).strip_ref().clone();
                let rhs = self.binary_text(op, (p.clone(), prec::ATOM), &pt, (tmp, prec::ATOM), &t, e.span)?;
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
                let rhs = self.binary_text(op, (p.clone(), prec::ATOM), &pt, v.clone(), &vt, e.span)?;
                // Keep `x op= v` where the target operator means the same thing.
                let plain = format!("{p} {} ", op.symbol());
                match rhs.0.strip_prefix(&plain) {
                    Some(_) => {
                        let v = self.shift_amount(op, v, &vt);
                        self.line(&format!("{p} {}= {};", op.symbol(), v.0));
                    }
                    None => self.line(&format!("{p} = {};", rhs.0)),
                }
            }
        }
        Ok(())
    }
}
