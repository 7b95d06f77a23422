//! Checks generated code with real front ends: WGSL is parsed and validated by naga (all
//! validation flags); GLSL ES 3.00 is parsed by glsl-lang (syntax only: naga cannot read
//! ES 3.00, and the GL backend's tests compile it with real drivers). Errors are reported
//! against the kernel's Rust source through the output's source map.

use std::fmt;

use crate::{Generated, SourceMapEntry, Target};

#[derive(Clone, Debug, thiserror::Error)]
pub struct ValidationError {
    pub target: Target,
    pub message: String,
    /// 1-based line of the generated code.
    pub line: u32,
    pub line_text: String,
    /// Where that line came from in the kernel's Rust source.
    pub rust: Option<SourceMapEntry>,
}

impl fmt::Display for ValidationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(r) = &self.rust {
            write!(f, "{}:{}:{}: in kernel fn `{}`: ", r.file, r.span.line, r.span.column + 1, r.function)?;
        }
        let what = match self.target {
            Target::GlslEs300 => "generated GLSL ES 3.00 does not parse",
            Target::Wgsl => "generated WGSL is invalid",
        };
        write!(f, "{what}: {} (generated line {}: `{}`)", self.message, self.line, self.line_text.trim())
    }
}

fn error_at(g: &Generated, offset: usize, message: String) -> ValidationError {
    let offset = offset.min(g.source.len());
    let line = g.source[..offset].matches('\n').count() as u32 + 1;
    let line_text = g.source.lines().nth(line as usize - 1).unwrap_or_default().to_string();
    ValidationError { target: g.target, message, line, line_text, rust: g.rust_location(line).cloned() }
}

/// Validates generated code for its target.
pub fn validate(g: &Generated) -> Result<(), ValidationError> {
    match g.target {
        Target::Wgsl => validate_wgsl(g).map(|_| ()),
        Target::GlslEs300 => validate_glsl(g),
    }
}

/// Parses and validates WGSL with naga, returning the module.
pub fn validate_wgsl(g: &Generated) -> Result<naga::Module, ValidationError> {
    let module = naga::front::wgsl::parse_str(&g.source).map_err(|e| {
        let offset = e.location(&g.source).map(|l| l.offset as usize).unwrap_or(0);
        error_at(g, offset, e.message().to_string())
    })?;
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default());
    validator.validate(&module).map_err(|e| {
        let offset = e.spans().next().and_then(|(s, _)| s.to_range()).map(|r| r.start).unwrap_or(0);
        let mut message = e.as_inner().to_string();
        let mut source: Option<&dyn std::error::Error> = std::error::Error::source(e.as_inner());
        while let Some(s) = source {
            message.push_str(": ");
            message.push_str(&s.to_string());
            source = s.source();
        }
        error_at(g, offset, message)
    })?;
    Ok(module)
}

/// Parses GLSL ES 3.00 with glsl-lang.
pub fn validate_glsl(g: &Generated) -> Result<(), ValidationError> {
    use glsl_lang::parse::DefaultParse;
    glsl_lang::ast::TranslationUnit::parse(g.source.as_str()).map_err(|e| {
        let offset = usize::from(e.pos().start());
        error_at(g, offset, e.to_string())
    })?;
    Ok(())
}
