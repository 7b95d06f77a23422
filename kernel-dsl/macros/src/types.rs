//! Types: Rust types of the DSL subset to IR types, and the messages for those it refuses.

use crate::{err_at, Lowering};
use kernel_dsl_ir as ir;

impl Lowering {
    pub(crate) fn ty(&mut self, t: &syn::Type) -> Option<ir::Type> {
        match t {
            syn::Type::Path(tp) => {
                if tp.qself.is_some() {
                    self.error(err_at(&t, "qualified types are not supported in kernels"));
                    return None;
                }
                let seg = tp.path.segments.last()?;
                let name = seg.ident.to_string();
                if tp.path.segments.len() > 1 {
                    let root = tp.path.segments[0].ident.to_string();
                    if !matches!(root.as_str(), "glam" | "kernel_dsl" | "super" | "crate" | "self") {
                        self.error(err_at(&t, "name kernel types directly (`Vec3`, `Hit`), not through a path"));
                        return None;
                    }
                }
                if let Some(msg) = unsupported_type_message(&name) {
                    self.error(err_at(&seg.ident, msg));
                    return None;
                }
                let mut args = Vec::new();
                match &seg.arguments {
                    syn::PathArguments::None => {}
                    syn::PathArguments::AngleBracketed(ab) => {
                        for a in &ab.args {
                            match a {
                                syn::GenericArgument::Type(t) => args.push(self.ty(t)?),
                                other => {
                                    self.error(err_at(
                                        &other,
                                        "only type arguments are supported here (`Texels<Vec4>`)",
                                    ));
                                    return None;
                                }
                            }
                        }
                    }
                    syn::PathArguments::Parenthesized(p) => {
                        self.error(err_at(&p, "function types are not supported in kernels"));
                        return None;
                    }
                }
                Some(ir::Type::Named { name, args })
            }
            syn::Type::Array(a) => {
                let elem = self.ty(&a.elem)?;
                let len = self.array_len(&a.len)?;
                Some(ir::Type::Array { elem: Box::new(elem), len })
            }
            syn::Type::Reference(r) => {
                if let Some(l) = &r.lifetime {
                    self.error(err_at(l, "lifetimes are not supported in kernels: leave them out (`scene: &Scene`)"));
                    return None;
                }
                let inner = self.ty(&r.elem)?;
                if r.mutability.is_none() {
                    let by_value = match &inner {
                        ir::Type::Named { name, .. } => match self.local_structs.get(name) {
                            Some(resources) => !resources,
                            None => ir::BUILTIN_TYPES.contains(&name.as_str()),
                        },
                        ir::Type::Array { .. } | ir::Type::Ref { .. } => true,
                    };
                    if by_value {
                        let what = match &inner {
                            ir::Type::Named { name, .. } => format!("`{name}`"),
                            _ => "it".to_string(),
                        };
                        self.error(err_at(
                            &r,
                            format!("shared references are only for the `#[resources]` struct: pass {what} by value (kernel values are Copy), or as `&mut` to modify it"),
                        ));
                        return None;
                    }
                }
                Some(ir::Type::Ref { mutable: r.mutability.is_some(), inner: Box::new(inner) })
            }
            syn::Type::Tuple(tt) if tt.elems.is_empty() => {
                self.error(err_at(&t, "leave out `-> ()`"));
                None
            }
            syn::Type::Tuple(_) => {
                self.error(err_at(&t, "tuples are not supported in kernels: declare a struct with named fields"));
                None
            }
            syn::Type::Slice(_) => {
                self.error(err_at(
                    &t,
                    "slices are not supported in kernels: use a fixed-size array `[T; N]`, or `Texels<T>` in the `#[resources]` struct for scene data",
                ));
                None
            }
            syn::Type::Paren(p) => self.ty(&p.elem),
            _ => {
                self.error(err_at(&t, "this type is not supported in kernels"));
                None
            }
        }
    }

    pub(crate) fn array_len(&mut self, e: &syn::Expr) -> Option<ir::ArrayLen> {
        match e {
            syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Int(i), .. }) => match i.base10_parse::<u32>() {
                Ok(n) => Some(ir::ArrayLen::Literal(n)),
                Err(_) => {
                    self.error(err_at(&i, "array length out of range"));
                    None
                }
            },
            syn::Expr::Path(p) if p.path.segments.len() == 1 => {
                Some(ir::ArrayLen::Const(p.path.segments[0].ident.to_string()))
            }
            _ => {
                self.error(err_at(&e, "array lengths must be an integer literal or a `const` name"));
                None
            }
        }
    }
}

pub(crate) fn unsupported_type_message(name: &str) -> Option<&'static str> {
    Some(match name {
        "f64" => "f64 is not supported on GPUs (WebGL2 has no doubles): use f32",
        "i64" | "u64" | "i128" | "u128" | "isize" => "64-bit integers are not supported on GPUs: use i32 or u32",
        "i8" | "i16" | "u8" | "u16" => "small integer types are not supported on GPUs: use i32 or u32 (and mask)",
        "char" | "str" | "String" => "strings and characters are not supported in kernels (GPUs have no text): use `u32` codes",
        "Vec" | "Box" | "Rc" | "Arc" | "HashMap" | "BTreeMap" | "VecDeque" => {
            "heap types are not supported in kernels: use fixed-size arrays `[T; N]`, or `Texels<T>` in the `#[resources]` struct for scene data"
        }
        "Option" | "Result" => "Option/Result are not supported in kernels: return a struct with a `hit: bool`-style flag",
        "DVec2" | "DVec3" | "DVec4" => "double-precision vectors are not supported on GPUs: use Vec2/Vec3/Vec4",
        "Vec3A" => "use Vec3 (Vec3A's padding has no GPU meaning)",
        _ => return None,
    })
}
