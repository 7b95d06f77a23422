// The test hook's compileProgram (tests/web/run.mjs compile, for examples/feature_sizes.rs):
// compiles and links a vertex and fragment shader (GLSL ES 3.00) on a WebGL2 context of its own
// and times it (see main.js's hook for what is measured).

let compileContext = null;
let compileCount = 0;

export function compileProgram(vertex, fragment) {
  compileCount++;
  const nonce = `\n// lightport compileProgram ${compileCount} ${performance.now()} ${Math.random()}\n`;
  if (!compileContext) {
    compileContext = document.createElement('canvas').getContext('webgl2');
    if (!compileContext) throw new Error('no WebGL2 context for compiling');
  }
  const gl = compileContext;
  const start = performance.now();
  const program = gl.createProgram();
  const shaders = [[gl.VERTEX_SHADER, vertex], [gl.FRAGMENT_SHADER, fragment]].map(([type, source]) => {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source + nonce);
    gl.compileShader(shader);
    gl.attachShader(program, shader);
    return shader;
  });
  gl.linkProgram(program);
  const ok = gl.getProgramParameter(program, gl.LINK_STATUS);
  const linked = performance.now();
  const ms = linked - start;
  let log = '';
  if (!ok) {
    log = [gl.getProgramInfoLog(program), ...shaders.map((s) => gl.getShaderInfoLog(s))].filter(Boolean).join('\n');
    if (gl.isContextLost()) log = `the WebGL context was lost. ${log}`;
  }
  for (const shader of shaders) {
    gl.detachShader(program, shader);
    gl.deleteShader(shader);
  }
  gl.deleteProgram(program);
  // A round trip to the GPU process, queued behind the deletion: ANGLE (Vulkan backend) keeps
  // building the program's pipeline in the background after LINK_STATUS, and deleting the
  // program waits for that. So the next measurement starts on an idle GPU process, and this
  // reports what the background work took.
  gl.finish();
  gl.getError();
  const settledMs = performance.now() - linked;
  return { ms, settledMs, ok: Boolean(ok), log };
}
