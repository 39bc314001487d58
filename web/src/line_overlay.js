// A line overlay for raw WebGL2 views (the brushed-metal panel's tangent field, web/src/brushed_panel.js): float32
// xyz segment pairs drawn in one colour through a view-projection, pulled slightly toward the viewer so that lines
// on the surface are not hidden by it.

const VS = `#version 300 es
in vec3 a_position; uniform mat4 u_view_projection;
void main() { gl_Position = u_view_projection * vec4(a_position, 1.0); gl_Position.z -= 0.002; }`;
const FS = `#version 300 es
precision mediump float; uniform vec3 u_colour; out vec4 o_color; void main() { o_color = vec4(u_colour, 1.0); }`;

export class LineOverlay {
  /** @param {WebGL2RenderingContext} gl */
  constructor(gl, colour = [0.1, 1.0, 0.4]) {
    this.gl = gl;
    this.colour = colour;
    this.prog = null;
  }

  /** Draw the segments (Float32Array of xyz pairs) into the bound framebuffer. */
  draw(viewProjection, lines) {
    const gl = this.gl;
    if (!this.prog) {
      this.prog = gl.createProgram();
      for (const [type, src] of [[gl.VERTEX_SHADER, VS], [gl.FRAGMENT_SHADER, FS]]) {
        const sh = gl.createShader(type);
        gl.shaderSource(sh, src);
        gl.compileShader(sh);
        gl.attachShader(this.prog, sh);
      }
      gl.linkProgram(this.prog);
      if (!gl.getProgramParameter(this.prog, gl.LINK_STATUS)) {
        throw new Error(`line overlay: ${gl.getProgramInfoLog(this.prog)}`);
      }
    }
    gl.useProgram(this.prog);
    gl.uniformMatrix4fv(gl.getUniformLocation(this.prog, 'u_view_projection'), false, viewProjection);
    gl.uniform3fv(gl.getUniformLocation(this.prog, 'u_colour'), this.colour);
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, lines, gl.STREAM_DRAW);
    const loc = gl.getAttribLocation(this.prog, 'a_position');
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    gl.drawArrays(gl.LINES, 0, lines.length / 3);
    gl.bindVertexArray(null);
    gl.deleteBuffer(buf);
    gl.deleteVertexArray(vao);
  }
}
