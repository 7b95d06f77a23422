//! Compiling and linking the generated shaders, and driver logs pointed back at the kernel's
//! Rust source.

use glow::HasContext;
use lightport_codegen::Generated;

use super::{gl_failed, GlError};

/// Compiles and links the generated fragment shader with codegen's full-screen vertex
/// shader. Compile errors carry the driver's log with each message's generated line mapped
/// back to the kernel's Rust source.
pub fn compile_program(gl: &glow::Context, fragment: &Generated) -> Result<glow::Program, GlError> {
    // SAFETY: object creation, compilation and linking on the current context; shaders are
    // deleted once linked (or on error), the program on error.
    unsafe {
        let vertex = compile_shader(gl, glow::VERTEX_SHADER, lightport_codegen::fullscreen_vertex_shader(), None)?;
        let fragment_shader = match compile_shader(gl, glow::FRAGMENT_SHADER, &fragment.source, Some(fragment)) {
            Ok(s) => s,
            Err(e) => {
                gl.delete_shader(vertex);
                return Err(e);
            }
        };
        let program = gl.create_program().map_err(gl_failed("glCreateProgram"))?;
        gl.attach_shader(program, vertex);
        gl.attach_shader(program, fragment_shader);
        gl.link_program(program);
        let linked = gl.get_program_link_status(program);
        gl.detach_shader(program, vertex);
        gl.detach_shader(program, fragment_shader);
        gl.delete_shader(vertex);
        gl.delete_shader(fragment_shader);
        if !linked {
            let log = gl.get_program_info_log(program);
            gl.delete_program(program);
            return Err(GlError::Link { log: annotate_log(&log, Some(fragment)) });
        }
        Ok(program)
    }
}

unsafe fn compile_shader(
    gl: &glow::Context,
    stage: u32,
    source: &str,
    generated: Option<&Generated>,
) -> Result<glow::Shader, GlError> {
    let shader = gl.create_shader(stage).map_err(gl_failed("glCreateShader"))?;
    gl.shader_source(shader, source);
    gl.compile_shader(shader);
    if gl.get_shader_compile_status(shader) {
        return Ok(shader);
    }
    let log = gl.get_shader_info_log(shader);
    gl.delete_shader(shader);
    let stage = if stage == glow::VERTEX_SHADER { "vertex" } else { "fragment" };
    Err(GlError::Compile { stage, log: annotate_log(&log, generated) })
}

/// The generated line a driver's log line refers to: Mesa writes `0:LINE(COLUMN): error: ...`,
/// ANGLE and others `ERROR: 0:LINE: ...`.
pub fn log_line_number(line: &str) -> Option<u32> {
    let bytes = line.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        // A source-string number, ':', the line number, then '(' or ':'.
        if bytes[i].is_ascii_digit() && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric()) {
            let mut j = i;
            while j < bytes.len() && bytes[j].is_ascii_digit() {
                j += 1;
            }
            if bytes.get(j) == Some(&b':') {
                let start = j + 1;
                let mut k = start;
                while k < bytes.len() && bytes[k].is_ascii_digit() {
                    k += 1;
                }
                if k > start && matches!(bytes.get(k), Some(b'(') | Some(b':')) {
                    return line[start..k].parse().ok();
                }
            }
            i = j;
        } else {
            i += 1;
        }
    }
    None
}

/// The driver's log with, under each message that names a generated line, that line and
/// the Rust location it was generated from.
pub fn annotate_log(log: &str, generated: Option<&Generated>) -> String {
    let mut out = String::new();
    for line in log.lines() {
        out.push_str(line);
        out.push('\n');
        let (Some(generated), Some(n)) = (generated, log_line_number(line)) else {
            continue;
        };
        if let Some(text) = generated.source.lines().nth((n as usize).saturating_sub(1)) {
            out.push_str(&format!("    generated line {n}: {}\n", text.trim()));
        }
        if let Some(at) = generated.rust_location(n) {
            out.push_str(&format!("    from {}:{}:{} (in {})\n", at.file, at.span.line, at.span.column, at.function));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::features::Features;
    use lightport_codegen::Target;

    #[test]
    fn driver_log_lines_are_parsed() {
        assert_eq!(log_line_number("0:123(45): error: `foo' undeclared"), Some(123));
        assert_eq!(log_line_number("ERROR: 0:77: 'foo' : undeclared identifier"), Some(77));
        assert_eq!(log_line_number("error: linking failed"), None);
        assert_eq!(log_line_number("vec3 at 0.5:1"), None);
    }

    #[test]
    fn log_messages_point_at_the_rust_source() {
        let features = Features { emissive_triangles: true, ..Default::default() };
        let generated = crate::kernel::path_tracer_shader(&features, Target::GlslEs300).expect("kernel");
        let n = generated.source.lines().position(|l| l.contains("power_heuristic(float")).expect("fn") as u32 + 2;
        let annotated = annotate_log(&format!("0:{n}(5): error: something"), Some(&generated));
        assert!(annotated.contains("tracer/src/kernel/"), "{annotated}");
        assert!(annotated.contains("power_heuristic"), "{annotated}");
    }
}
