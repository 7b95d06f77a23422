//! Identifiers in generated code: Rust names are kept unless they clash with a keyword,
//! reserved word, reserved prefix or built-in of any target language
//! ([`crate::language::Language::reserved_words`]), in which case `_` is appended. The union of
//! every language's words decides, so that a kernel's names are the same in every output.

use std::collections::BTreeSet;

use crate::Target;

/// Whether `name` is reserved in some target language, or by codegen itself (`lp_`).
fn reserved(name: &str) -> bool {
    name.starts_with("lp_")
        || Target::ALL
            .iter()
            .map(|t| t.language())
            .any(|l| l.reserved_words().contains(&name) || l.reserved_prefixes().iter().any(|p| name.starts_with(p)))
}

/// A Rust identifier as it appears in generated code.
pub(crate) fn safe(name: &str) -> String {
    if reserved(name) {
        format!("{name}_")
    } else if name.contains("__") {
        // Shading languages reserve double underscores.
        name.replace("__", "_u_")
    } else {
        name.to_string()
    }
}

/// A fresh name for a local binding: its Rust name where possible, else numbered
/// (`x`, `x_1`, ...) so that Rust's shadowing (`let x = ...; let x = x * 2.0;`) survives in
/// languages that forbid redeclaration in one scope. `used` holds the function's names so far;
/// `global` says whether a name is taken program-wide (a function, struct, ...): asked, not
/// copied into `used`, since a program has hundreds of such names and a kernel hundreds of
/// functions.
pub(crate) fn unique_local(name: &str, used: &mut BTreeSet<String>, global: impl Fn(&str) -> bool) -> String {
    let base = safe(name);
    let mut candidate = base.clone();
    let mut n = 1;
    while used.contains(&candidate) || global(&candidate) {
        // Never create a double underscore (reserved in shading languages).
        candidate = if base.ends_with('_') { format!("{base}{n}") } else { format!("{base}_{n}") };
        n += 1;
    }
    used.insert(candidate.clone());
    candidate
}
