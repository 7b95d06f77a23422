//! `#[kernel]`: emits the module unchanged for rustc (so it runs on the CPU) and, beside it,
//! its IR as `kernel_ir()`. Anything outside the supported subset is a compile error at the
//! offending span, with a message that says what to write instead.
//!
//! The lowering is one `Lowering` pass over the module in three files: this one (the module,
//! its imports, structs, consts, function signatures and the recursion check), `types.rs`
//! (Rust types to IR types) and `expr.rs` (blocks, statements and expressions).

use std::collections::{BTreeMap, BTreeSet};

mod expr;
mod source_tag;
mod types;

use expr::macro_message;

use kernel_dsl_ir as ir;
use proc_macro2::{Span, TokenStream};
use quote::quote;
use syn::spanned::Spanned;
use syn::Error;

#[proc_macro_attribute]
pub fn kernel(attr: proc_macro::TokenStream, item: proc_macro::TokenStream) -> proc_macro::TokenStream {
    let file = source_tag::crate_relative(&proc_macro::Span::call_site().file());
    expand(attr.into(), item.into(), file).into()
}

fn expand(attr: TokenStream, item: TokenStream, file: String) -> TokenStream {
    let compute = match syn::parse2::<Option<syn::Ident>>(attr.clone()) {
        Ok(None) => false,
        Ok(Some(i)) if i == "compute" => true,
        _ => {
            return Error::new(
                attr.span(),
                "`#[kernel]` takes no arguments, or `compute` (`#[kernel(compute)]`: a compute module, with storage and atomics, for WGSL and the CPU)",
            )
            .to_compile_error()
        }
    };
    let mut module: syn::ItemMod = match syn::parse2(item) {
        Ok(m) => m,
        Err(e) => {
            return Error::new(e.span(), "`#[kernel]` applies to an inline module: `#[kernel] pub mod name { ... }`")
                .to_compile_error()
        }
    };
    let mut lowering = Lowering { compute, ..Lowering::default() };
    let ir = lowering.module(&module, file);
    let resource_impls = resources_impls(&module);
    strip_dsl_attributes(&mut module);
    let errors = lowering.errors.into_iter().reduce(|mut a, b| {
        a.combine(b);
        a
    });
    match (ir, errors) {
        (Some(ir), None) => {
            let json = ir.to_json();
            let Some((brace, items)) = module.content.as_mut() else { unreachable!("checked by Lowering::module") };
            let _ = brace;
            let generated: syn::File = syn::parse_quote! {
                /// The IR of this kernel module, for code generation.
                #[doc(hidden)]
                pub const KERNEL_IR_JSON: &str = #json;
                /// This kernel module's IR, for `lightport-codegen`.
                pub fn kernel_ir() -> ::kernel_dsl::ir::Module {
                    ::kernel_dsl::ir::Module::from_json(KERNEL_IR_JSON)
                }
            };
            items.extend(generated.items);
            items.extend(resource_impls);
            quote!(#module)
        }
        (_, Some(err)) => {
            let err = err.to_compile_error();
            quote!(#err #module)
        }
        (None, None) => quote!(#module),
    }
}

/// `impl kernel_dsl::Resources` for each `#[resources]` struct: its fields by name, in
/// declaration order, so hosts walk the one declaration instead of copying its field list.
fn resources_impls(module: &syn::ItemMod) -> Vec<syn::Item> {
    let Some((_, items)) = &module.content else { return Vec::new() };
    let structs = items.iter().filter_map(|item| match item {
        syn::Item::Struct(s) if s.attrs.iter().any(|a| a.path().is_ident("resources")) => Some(s),
        _ => None,
    });
    structs
        .filter_map(|s| {
            let ident = &s.ident;
            let syn::Fields::Named(named) = &s.fields else { return None };
            let fields: Vec<&syn::Ident> = named.named.iter().filter_map(|f| f.ident.as_ref()).collect();
            let names: Vec<String> = fields.iter().map(|f| f.to_string()).collect();
            Some(syn::parse_quote! {
                impl ::kernel_dsl::Resources for #ident {
                    fn fields(&self) -> ::std::vec::Vec<(&'static str, ::kernel_dsl::Resource<'_>)> {
                        ::std::vec![#((#names, ::kernel_dsl::ResourceField::resource(&self.#fields))),*]
                    }
                    fn fields_mut(&mut self) -> ::std::vec::Vec<(&'static str, ::kernel_dsl::ResourceMut<'_>)> {
                        ::std::vec![#((#names, ::kernel_dsl::ResourceField::resource_mut(&mut self.#fields))),*]
                    }
                }
            })
        })
        .collect()
}

/// Removes the DSL's marker attributes (`#[resources]`) so rustc sees plain Rust.
fn strip_dsl_attributes(module: &mut syn::ItemMod) {
    if let Some((_, items)) = module.content.as_mut() {
        for item in items {
            if let syn::Item::Struct(s) = item {
                s.attrs.retain(|a| !a.path().is_ident("resources"));
            }
        }
    }
}

/// The error for a compute construct (`Storage`, `Atomics`, their methods) in a module without
/// `#[kernel(compute)]`.
pub(crate) fn needs_compute(what: &str) -> String {
    format!(
        "{what} needs compute: GLSL ES 3.00 (WebGL2) has no storage buffers or atomics. Write it in a `#[kernel(compute)]` module, which is generated for WGSL and the CPU only"
    )
}

fn span_of(s: Span) -> ir::Span {
    let start = s.start();
    ir::Span { line: start.line as u32, column: start.column as u32 }
}

fn err(span: Span, msg: impl std::fmt::Display) -> Error {
    Error::new(span, msg)
}

/// An error covering all of `tokens` (on stable Rust, `Spanned::span` of a multi-token node
/// is only its first token, so `err(node.span(), ..)` would underline one token).
fn err_at<T: quote::ToTokens + ?Sized>(tokens: &T, msg: impl std::fmt::Display) -> Error {
    Error::new_spanned(tokens, msg)
}

#[derive(Default)]
struct Lowering {
    errors: Vec<Error>,
    /// Local function name -> calls it makes to local functions (for the recursion check).
    calls: BTreeMap<String, Vec<(String, Span)>>,
    current_fn: Option<String>,
    local_fns: BTreeSet<String>,
    /// Structs declared in this module -> whether they are the `#[resources]` struct.
    local_structs: BTreeMap<String, bool>,
    /// Consts declared in this module and names imported from other kernel modules: the
    /// identifiers a `match` arm may name as a constant pattern.
    pattern_consts: BTreeSet<String>,
    /// Names imported by `use` from other (kernel) modules, and whether a glob import exists.
    imported: BTreeSet<String>,
    glob_import: bool,
    /// `#[kernel(compute)]`: `Storage`/`Atomics` resources and their methods are allowed.
    compute: bool,
}

impl Lowering {
    fn error(&mut self, e: Error) {
        self.errors.push(e);
    }

    fn module(&mut self, module: &syn::ItemMod, file: String) -> Option<ir::Module> {
        let Some((_, items)) = &module.content else {
            self.error(err_at(
                &module,
                "`#[kernel]` needs an inline module: `#[kernel] pub mod name { ... }` (out-of-line modules are not visible to the macro)",
            ));
            return None;
        };
        for item in items {
            if let syn::Item::Use(u) = item {
                let mut flat = Vec::new();
                flatten_use(&u.tree, &mut Vec::new(), &mut flat);
                for (path, name, _, _) in flat {
                    if matches!(path.first().map(String::as_str), Some("glam" | "kernel_dsl" | "core" | "std")) {
                        continue;
                    }
                    match name {
                        Some(n) => {
                            self.imported.insert(n);
                        }
                        None => self.glob_import = true,
                    }
                }
            }
        }
        self.local_fns = items
            .iter()
            .filter_map(|i| match i {
                syn::Item::Fn(f) => Some(f.sig.ident.to_string()),
                _ => None,
            })
            .collect();
        self.local_structs = items
            .iter()
            .filter_map(|i| match i {
                syn::Item::Struct(s) => {
                    Some((s.ident.to_string(), s.attrs.iter().any(|a| a.path().is_ident("resources"))))
                }
                _ => None,
            })
            .collect();
        for item in items {
            match item {
                syn::Item::Const(c) => {
                    self.pattern_consts.insert(c.ident.to_string());
                }
                syn::Item::Use(u) => {
                    let mut flat = Vec::new();
                    flatten_use(&u.tree, &mut Vec::new(), &mut flat);
                    self.pattern_consts.extend(flat.into_iter().filter_map(|(_, name, _, _)| name));
                }
                _ => {}
            }
        }
        let mut out =
            ir::Module { name: module.ident.to_string(), file, imports: vec![], items: vec![], compute: self.compute };
        for item in items {
            if is_cfg_test(item) {
                continue;
            }
            match item {
                syn::Item::Use(u) => self.use_item(u, &mut out.imports),
                syn::Item::Struct(s) => {
                    if let Some(s) = self.struct_item(s) {
                        out.items.push(ir::Item::Struct(s));
                    }
                }
                syn::Item::Const(c) => {
                    if let Some(c) = self.const_item(c) {
                        out.items.push(ir::Item::Const(c));
                    }
                }
                syn::Item::Fn(f) => {
                    if let Some(f) = self.fn_item(f) {
                        out.items.push(ir::Item::Fn(f));
                    }
                }
                syn::Item::Impl(i) => self.error(err(
                    i.impl_token.span,
                    "`impl` blocks are not supported in kernels: write free functions that take the value as a parameter",
                )),
                syn::Item::Trait(t) => self.error(err(
                    t.trait_token.span,
                    "traits are not supported in kernels: write free functions",
                )),
                syn::Item::Enum(e) => self.error(err(
                    e.enum_token.span,
                    "enums are not supported in kernels: use `u32` constants (`const KIND_X: u32 = 0;`)",
                )),
                syn::Item::Static(s) => self.error(err(
                    s.static_token.span,
                    "statics are not supported in kernels: use a `const`, or a field of the `#[resources]` struct for data that changes",
                )),
                syn::Item::Macro(m) => self.error(err_at(&m.mac.path, macro_message(&m.mac))),
                syn::Item::Type(t) => self.error(err(
                    t.type_token.span,
                    "type aliases are not supported in kernels: name the type directly",
                )),
                syn::Item::Mod(m) => self.error(err(
                    m.mod_token.span,
                    "nested modules are not supported in a kernel module: make it a separate `#[kernel]` module",
                )),
                other => self.error(err_at(&other, "this item is not supported in a kernel module")),
            }
        }
        self.check_recursion();
        Some(out)
    }

    fn use_item(&mut self, u: &syn::ItemUse, imports: &mut Vec<ir::Import>) {
        let mut flat = Vec::new();
        flatten_use(&u.tree, &mut Vec::new(), &mut flat);
        // path -> names (None = glob)
        let mut grouped: BTreeMap<Vec<String>, Option<Vec<String>>> = BTreeMap::new();
        for rename in use_renames(&u.tree) {
            self.error(err_at(
                rename,
                "renaming imports (`as`) is not supported in kernels: import the item under its own name",
            ));
        }
        for (path, name, span, renamed) in flat {
            if renamed {
                continue;
            }
            let root = path.first().map(String::as_str).unwrap_or("");
            if matches!(root, "glam" | "kernel_dsl" | "core" | "std") {
                // Vocabulary of the subset (glam types, Texels, f32 consts): nothing to link.
                continue;
            }
            if path.is_empty() {
                self.error(err(
                    span,
                    "import kernel items through their module path, e.g. `use super::rng::random_float;`",
                ));
                continue;
            }
            match name {
                None => {
                    grouped.insert(path, None);
                }
                Some(n) => {
                    if let Some(Some(names)) = grouped.get_mut(&path) {
                        names.push(n);
                    } else {
                        grouped.entry(path).or_insert_with(|| Some(vec![n]));
                    }
                }
            }
        }
        let span = span_of(u.span());
        for (path, names) in grouped {
            imports.push(ir::Import { path, names, span });
        }
    }

    fn struct_item(&mut self, s: &syn::ItemStruct) -> Option<ir::StructDef> {
        if !s.generics.params.is_empty() {
            self.error(err_at(
                &s.generics,
                "generic structs are not supported in kernels: declare one struct per concrete type",
            ));
            return None;
        }
        let resources = s.attrs.iter().any(|a| a.path().is_ident("resources"));
        let mut group = 0;
        for a in s.attrs.iter().filter(|a| a.path().is_ident("resources")) {
            if let syn::Meta::List(_) = &a.meta {
                let parsed = a.parse_nested_meta(|meta| {
                    if meta.path.is_ident("group") {
                        let n: syn::LitInt = meta.value()?.parse()?;
                        group = n.base10_parse::<u32>()?;
                        Ok(())
                    } else {
                        Err(meta.error("`#[resources]` takes `group = N` (the WGSL bind group of its bindings)"))
                    }
                });
                if let Err(e) = parsed {
                    self.error(e);
                }
            }
        }
        let syn::Fields::Named(named) = &s.fields else {
            self.error(err_at(&s.ident, "kernel structs need named fields: `struct Hit { t: f32, ... }`"));
            return None;
        };
        let mut fields = Vec::new();
        for f in &named.named {
            let name = f.ident.as_ref().map(|i| i.to_string()).unwrap_or_default();
            if let Some(ty) = self.ty(&f.ty) {
                if let ir::Type::Named { name: ty_name, .. } = &ty {
                    if ir::COMPUTE_TYPES.contains(&ty_name.as_str()) {
                        if !self.compute {
                            self.error(err_at(&f.ty, needs_compute(&format!("`{ty_name}`"))));
                        } else if !resources {
                            self.error(err_at(
                                &f.ty,
                                format!(
                                    "`{ty_name}` is a resource: declare it in a `#[resources]` struct (the host binds it; kernel values are plain data)"
                                ),
                            ));
                        }
                    }
                }
                fields.push(ir::Field { name, ty, span: span_of(f.span()) });
            }
        }
        Some(ir::StructDef { name: s.ident.to_string(), fields, resources, group, span: span_of(s.ident.span()) })
    }

    fn const_item(&mut self, c: &syn::ItemConst) -> Option<ir::ConstDef> {
        let ty = self.ty(&c.ty)?;
        let value = self.expr(&c.expr)?;
        Some(ir::ConstDef { name: c.ident.to_string(), ty, value, span: span_of(c.ident.span()) })
    }

    fn fn_item(&mut self, f: &syn::ItemFn) -> Option<ir::FnDef> {
        let sig = &f.sig;
        if !sig.generics.params.is_empty() {
            let only_lifetimes = sig.generics.params.iter().all(|p| matches!(p, syn::GenericParam::Lifetime(_)));
            self.error(err_at(
                &sig.generics,
                if only_lifetimes {
                    "lifetimes are not supported in kernels: leave them out (`scene: &Scene`)"
                } else {
                    "generic functions are not supported in kernels: write one function per concrete type"
                },
            ));
            return None;
        }
        if let Some(t) = &sig.asyncness {
            self.error(err(t.span, "async functions are not supported in kernels"));
        }
        if let Some(t) = &sig.unsafety {
            self.error(err(t.span, "unsafe functions are not supported in kernels"));
        }
        if let Some(v) = &sig.variadic {
            self.error(err_at(&v, "variadic functions are not supported in kernels"));
        }
        let name = sig.ident.to_string();
        self.current_fn = Some(name.clone());
        let mut params = Vec::new();
        for input in &sig.inputs {
            match input {
                syn::FnArg::Receiver(r) => self.error(err_at(
                    &r,
                    "methods are not supported in kernels: write a free function that takes the value as a parameter",
                )),
                syn::FnArg::Typed(pt) => {
                    let (pname, mutable) = match &*pt.pat {
                        syn::Pat::Ident(pi) if pi.by_ref.is_none() && pi.subpat.is_none() => {
                            (pi.ident.to_string(), pi.mutability.is_some())
                        }
                        other => {
                            self.error(err_at(&other, "kernel parameters must be plain names: `x: f32`"));
                            continue;
                        }
                    };
                    if let Some(ty) = self.ty(&pt.ty) {
                        params.push(ir::Param { name: pname, ty, mutable, span: span_of(pt.span()) });
                    }
                }
            }
        }
        let ret = match &sig.output {
            syn::ReturnType::Default => None,
            syn::ReturnType::Type(_, t) => self.ty(t),
        };
        let body = self.block(&f.block);
        self.current_fn = None;
        Some(ir::FnDef { name, params, ret, body: body?, span: span_of(sig.ident.span()) })
    }

    fn check_recursion(&mut self) {
        // Depth-first search for a cycle in the local call graph.
        fn visit(
            name: &str,
            calls: &BTreeMap<String, Vec<(String, Span)>>,
            stack: &mut Vec<String>,
            done: &mut BTreeSet<String>,
        ) -> Option<(String, Span)> {
            if done.contains(name) {
                return None;
            }
            stack.push(name.to_string());
            for (callee, span) in calls.get(name).into_iter().flatten() {
                if let Some(start) = stack.iter().position(|s| s == callee) {
                    let mut cycle: Vec<String> = stack[start..].iter().map(|s| format!("`{s}`")).collect();
                    cycle.push(format!("`{callee}`"));
                    return Some((cycle.join(" -> "), *span));
                }
                if let Some(found) = visit(callee, calls, stack, done) {
                    return Some(found);
                }
            }
            stack.pop();
            done.insert(name.to_string());
            None
        }
        let mut done = BTreeSet::new();
        let names: Vec<String> = self.calls.keys().cloned().collect();
        for name in names {
            let mut stack = Vec::new();
            if let Some((cycle, span)) = visit(&name, &self.calls, &mut stack, &mut done) {
                self.error(err(
                    span,
                    format!(
                        "recursion is not supported on GPUs (this call closes the cycle {cycle}): use a loop, with an explicit stack if needed"
                    ),
                ));
                return;
            }
        }
    }
}

/// The `a as b` parts of a `use` tree.
fn use_renames(tree: &syn::UseTree) -> Vec<&syn::UseRename> {
    match tree {
        syn::UseTree::Path(p) => use_renames(&p.tree),
        syn::UseTree::Rename(r) => vec![r],
        syn::UseTree::Group(g) => g.items.iter().flat_map(use_renames).collect(),
        syn::UseTree::Name(_) | syn::UseTree::Glob(_) => vec![],
    }
}

/// Flattens a `use` tree into (module path, imported name or `None` for a glob, span, renamed).
#[allow(clippy::type_complexity)]
fn flatten_use(
    tree: &syn::UseTree,
    prefix: &mut Vec<String>,
    out: &mut Vec<(Vec<String>, Option<String>, Span, bool)>,
) {
    match tree {
        syn::UseTree::Path(p) => {
            prefix.push(p.ident.to_string());
            flatten_use(&p.tree, prefix, out);
            prefix.pop();
        }
        syn::UseTree::Name(n) => out.push((prefix.clone(), Some(n.ident.to_string()), n.ident.span(), false)),
        syn::UseTree::Rename(r) => out.push((prefix.clone(), Some(r.ident.to_string()), r.ident.span(), true)),
        syn::UseTree::Glob(g) => out.push((prefix.clone(), None, g.star_token.span, false)),
        syn::UseTree::Group(g) => {
            for t in &g.items {
                flatten_use(t, prefix, out);
            }
        }
    }
}

fn is_cfg_test(item: &syn::Item) -> bool {
    let attrs = match item {
        syn::Item::Mod(m) => &m.attrs,
        syn::Item::Fn(f) => &f.attrs,
        syn::Item::Use(u) => &u.attrs,
        syn::Item::Const(c) => &c.attrs,
        syn::Item::Struct(s) => &s.attrs,
        _ => return false,
    };
    attrs.iter().any(|a| a.path().is_ident("cfg") && a.parse_args::<syn::Ident>().map(|i| i == "test").unwrap_or(false))
}

/// `KIND_LAMBERT`: the naming convention of constants.
fn is_screaming_case(name: &str) -> bool {
    name.chars().any(|c| c.is_ascii_uppercase())
        && name.chars().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
}
