//! What the `lightport` command shares with its examples and tests: child processes tied to
//! this one ([`serve_child`], e.g. `lightport serve` for a browser test) and the load generator
//! for `lightport serve` ([`load`]). The command itself is `src/main.rs`.

pub mod load;
pub mod serve_child;
