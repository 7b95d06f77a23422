//! Specialisation: resource fields fixed at code-generation time ([`crate::Selection::specialize`])
//! become literals, and the conditions they decide are evaluated here so that the lowering
//! emits only the live branch. Integer consts can be fixed too (a key without a `.`): the
//! program is emitted with the const's value replaced, array lengths included.

use std::collections::BTreeMap;

use super::{strip_parens, Lowerer, R};
use crate::ir::{self, BinOp, Expr, ExprKind as K, UnOp};
use crate::types::{Scalar, Ty};
use crate::{infer, CodegenError, Program};

/// `program` with each const named in `specialize` (keys without a `.`) set to its value, or
/// None when no const is fixed. Only integer consts can be fixed (array lengths, loop bounds).
pub(super) fn fix_consts(program: &Program, specialize: &BTreeMap<String, u32>) -> R<Option<Program>> {
    let fixed: Vec<(&String, u32)> =
        specialize.iter().filter(|(k, _)| !k.contains('.')).map(|(k, v)| (k, *v)).collect();
    if fixed.is_empty() {
        return Ok(None);
    }
    let mut program = program.clone();
    for (name, value) in fixed {
        let ty = program.consts.get(name).map(|c| infer::resolve_type(&program, &c.item.ty));
        let Some(c) = program.consts.get_mut(name) else {
            return Err(CodegenError {
                file: String::new(),
                span: ir::Span::default(),
                function: None,
                message: format!("specialisation fixes `{name}`, which is not a kernel const"),
            });
        };
        if !matches!(ty, Some(Ok(Ty::Scalar(Scalar::U32 | Scalar::I32 | Scalar::USize)))) {
            return Err(CodegenError {
                file: c.file.clone(),
                span: c.item.span,
                function: None,
                message: format!("specialisation fixes `{name}`, but only integer consts can be fixed"),
            });
        }
        let suffix = match &c.item.value.kind {
            K::Lit(ir::Lit::Int { suffix, .. }) => suffix.clone(),
            _ => None,
        };
        c.item.value.kind = K::Lit(ir::Lit::Int { digits: value.to_string(), value: u64::from(value), suffix });
    }
    Ok(Some(program))
}

impl Lowerer<'_> {
    /// The value of a condition fixed by specialisation (`res.flag != 0 && ...`), if any.
    pub(super) fn const_bool(&self, e: &Expr) -> Option<bool> {
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

    /// The value a resource field is fixed to, if it is.
    pub(super) fn specialized(&self, res: &str, field: &str) -> Option<u32> {
        self.selection.specialize.get(&format!("{res}.{field}")).copied()
    }
}
