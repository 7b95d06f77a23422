//! The equivalence-test harness: the layout of a kernel function's arguments and results as
//! 32-bit words (see [`crate::Harness`]), and the expressions that decode and encode them. The
//! shader around them is the language's ([`crate::language::Language::harness_shader`]).

use std::fmt::Write as _;

use super::{Lowerer, R};
use crate::infer;
use crate::ir;
use crate::language::{HarnessArg, HarnessShader, ResourceBlock};
use crate::names;
use crate::types::Ty;
use crate::{CodegenError, Harness, HarnessWord};

impl Lowerer<'_> {
    fn harness_error(&self, message: impl Into<String>) -> CodegenError {
        CodegenError { file: String::new(), span: ir::Span::default(), function: None, message: message.into() }
    }

    /// An expression decoding a `t` from the words starting at `*next`; each word's Rust path
    /// (`origin.x`, `ray.dir.z`) and scalar type is appended to `layout`.
    fn decode(&mut self, t: &Ty, path: &str, next: &mut u32, layout: &mut Vec<HarnessWord>) -> R<String> {
        Ok(match t {
            Ty::Scalar(s) => {
                let w = self.lang.harness_word(*next);
                *next += 1;
                layout.push(HarnessWord { path: path.to_string(), scalar: *s });
                self.lang.decode_word(*s, &w)
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
        layout: &mut Vec<HarnessWord>,
    ) -> R<()> {
        match t {
            Ty::Scalar(s) => {
                let w = self.lang.encode_word(*s, value);
                lines.push(format!("lp_w[{}] = {w};", *next));
                layout.push(HarnessWord { path: path.to_string(), scalar: *s });
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

    /// A harness binds its own arguments, results and count in bind group 1 (WGSL: `lp_args`,
    /// `lp_results`, `lp_count`), so `function` may only reach resources of group 0: one that
    /// reads a `#[resources(group = N)]` struct with N >= 1 (the wavefront's stages read `Paths`,
    /// group 1, and `Dispatch`, group 2) is refused at the function, for every target, instead
    /// of sharing the harness's bindings. `blocks` are the resources the emitted code uses.
    pub(super) fn refuse_grouped_resources(&self, function: &str, blocks: &[ResourceBlock]) -> R<()> {
        let Some(block) = blocks.iter().find(|b| b.group >= 1) else { return Ok(()) };
        let Some(f) = self.program.fns.get(function) else { return Ok(()) };
        Err(CodegenError {
            file: f.file.clone(),
            span: f.item.span,
            function: Some(format!("{}::{}", f.module, f.item.name)),
            message: format!(
                "no equivalence harness around `{function}`: it reads `{}`, a `#[resources(group = {})]` struct, \
                 and a harness binds its own arguments and results in bind group 1; only functions whose \
                 resources are all in group 0 can be harnessed (test this one through the pipeline that binds \
                 its groups, or harness the group-0 functions it calls)",
                block.name, block.group
            ),
        })
    }

    /// The harness shader around `function` and its layout.
    pub(super) fn harness(&mut self, function: &str) -> R<(String, Harness)> {
        let f = self
            .program
            .fns
            .get(function)
            .ok_or_else(|| self.harness_error(format!("`{function}` is not a kernel function")))?;
        let types = infer::infer_fn(self.program, f)?;
        let param_names: Vec<String> = f.item.params.iter().map(|p| p.name.clone()).collect();
        let mut next = 0u32;
        let mut args = Vec::new();
        let mut outs = Vec::new();
        let mut inputs = Vec::new();
        let mut outputs = Vec::new();
        for (i, id) in types.params.iter().enumerate() {
            let b = &types.bindings[*id];
            let param = param_names.get(i).cloned().unwrap_or_else(|| format!("arg{i}"));
            let (t, by_ref) = match &b.ty {
                Ty::Resource(_) => continue,
                Ty::RefMut(inner) => ((**inner).clone(), true),
                t => (t.clone(), false),
            };
            let name = format!("lp_arg{i}");
            let value = self.decode(&t, &param, &mut next, &mut inputs)?;
            let type_name = self.ty_name(&t);
            args.push(HarnessArg { name: name.clone(), type_name, value, by_ref });
            if by_ref {
                outs.push((t, name, param));
            }
        }
        let input_words = next;
        let mut stores = Vec::new();
        let mut out_next = 0u32;
        let result_type = if types.ret != Ty::Unit {
            let ret = types.ret.clone();
            let tn = self.ty_name(&ret);
            self.encode(&ret, "lp_result", "return", &mut out_next, &mut stores, &mut outputs)?;
            Some(tn)
        } else {
            None
        };
        for (t, name, param) in &outs {
            self.encode(t, name, param, &mut out_next, &mut stores, &mut outputs)?;
        }
        let layout = Harness { function: function.to_string(), input_words, output_words: out_next, inputs, outputs };
        let mut text = String::new();
        let _ = writeln!(
            text,
            "// Equivalence-test harness around {function}: {input_words} input words, {out_next} output words."
        );
        let shader = HarnessShader { layout: &layout, function: names::safe(function), args, result_type, stores };
        text.push_str(&self.lang.harness_shader(&shader));
        Ok((text, layout))
    }
}
