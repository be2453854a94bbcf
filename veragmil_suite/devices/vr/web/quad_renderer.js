// A small WebGL2 renderer for what the operator sees in VR: textured quads (the camera stream, the status
// line) and flat-coloured boxes (the controllers). Hand-written instead of vendoring three.js: the scene is two
// quads and two boxes, about 150 lines of WebGL against a 1.2 MB library to serve and update.

import { multiply, scaling } from "./mat4.js";

const VERTEX = `#version 300 es
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec2 a_uv;
layout(location = 2) in float a_shade;
uniform mat4 u_mvp;
out vec2 v_uv;
out float v_shade;
void main() {
  v_uv = a_uv;
  v_shade = a_shade;
  gl_Position = u_mvp * vec4(a_position, 1.0);
}`;

const FRAGMENT = `#version 300 es
precision mediump float;
uniform sampler2D u_texture;
uniform bool u_textured;
uniform vec4 u_color;
in vec2 v_uv;
in float v_shade;
out vec4 color;
void main() {
  color = u_textured ? texture(u_texture, v_uv) : vec4(u_color.rgb * v_shade, u_color.a);
}`;

function compile(gl, type, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) {
    throw new Error("shader: " + gl.getShaderInfoLog(shader));
  }
  return shader;
}

// Interleaved x, y, z, u, v, shade.
function quadVertices() {
  // a unit quad in the xy plane facing +z; v = 0 at the top (the first image row)
  return new Float32Array([
    -0.5, -0.5, 0, 0, 1, 1, 0.5, -0.5, 0, 1, 1, 1, 0.5, 0.5, 0, 1, 0, 1,
    -0.5, -0.5, 0, 0, 1, 1, 0.5, 0.5, 0, 1, 0, 1, -0.5, 0.5, 0, 0, 0, 1,
  ]);
}

function boxVertices() {
  // a unit cube; each face shaded differently so its orientation reads without lighting
  const faces = [
    [[1, 0, 0], [0, 1, 0], [0, 0, 1], 0.9],
    [[-1, 0, 0], [0, 0, 1], [0, 1, 0], 0.6],
    [[0, 1, 0], [0, 0, 1], [1, 0, 0], 1.0],
    [[0, -1, 0], [1, 0, 0], [0, 0, 1], 0.4],
    [[0, 0, 1], [1, 0, 0], [0, 1, 0], 0.8],
    [[0, 0, -1], [0, 1, 0], [1, 0, 0], 0.5],
  ];
  const out = [];
  for (const [n, a, b, shade] of faces) {
    const corner = (sa, sb) => [0, 1, 2].map((i) => 0.5 * n[i] + 0.5 * sa * a[i] + 0.5 * sb * b[i]);
    for (const [sa, sb] of [[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]]) {
      out.push(...corner(sa, sb), 0, 0, shade);
    }
  }
  return new Float32Array(out);
}

export class QuadRenderer {
  constructor(gl) {
    this.gl = gl;
    const program = gl.createProgram();
    gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, VERTEX));
    gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, FRAGMENT));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
      throw new Error("program: " + gl.getProgramInfoLog(program));
    }
    this.program = program;
    this.u = {
      mvp: gl.getUniformLocation(program, "u_mvp"),
      texture: gl.getUniformLocation(program, "u_texture"),
      textured: gl.getUniformLocation(program, "u_textured"),
      color: gl.getUniformLocation(program, "u_color"),
    };
    this.quad = this._mesh(quadVertices());
    this.box = this._mesh(boxVertices());
  }

  _mesh(data) {
    const gl = this.gl;
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    const stride = 6 * 4;
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, stride, 0);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 2, gl.FLOAT, false, stride, 12);
    gl.enableVertexAttribArray(2);
    gl.vertexAttribPointer(2, 1, gl.FLOAT, false, stride, 20);
    gl.bindVertexArray(null);
    return { vao, count: data.length / 6 };
  }

  // A texture to be filled from an ImageBitmap or a canvas with upload().
  createTexture() {
    const gl = this.gl;
    const texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, 1, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array([20, 20, 30, 255]));
    return texture;
  }

  upload(texture, source) {
    const gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, source);
  }

  // items: [{kind: "quad" | "box", model: mat4, size: [w, h, d], texture?, color?: [r, g, b, a]}]
  draw(projection, view, items) {
    const gl = this.gl;
    gl.useProgram(this.program);
    gl.enable(gl.DEPTH_TEST);
    gl.disable(gl.CULL_FACE);
    gl.activeTexture(gl.TEXTURE0);
    gl.uniform1i(this.u.texture, 0);
    const viewProjection = multiply(projection, view);
    for (const item of items) {
      const mesh = item.kind === "box" ? this.box : this.quad;
      const [w, h, d] = item.size;
      gl.uniformMatrix4fv(this.u.mvp, false, multiply(viewProjection, multiply(item.model, scaling(w, h, d))));
      gl.uniform1i(this.u.textured, item.texture ? 1 : 0);
      if (item.texture) gl.bindTexture(gl.TEXTURE_2D, item.texture);
      gl.uniform4fv(this.u.color, item.color || [1, 1, 1, 1]);
      gl.bindVertexArray(mesh.vao);
      gl.drawArrays(gl.TRIANGLES, 0, mesh.count);
    }
    gl.bindVertexArray(null);
  }
}
