// GLSL loader for the browser, the twin of relight/gl/shaders.py (byte-identical output; web/test/shaders.test.js):
// "#version 300 es" and default precisions, one "#define NAME value" per define, then the source with every
// #include "name" replaced by that file (each file once per stage).

const INCLUDE = /^[ \t]*#[ \t]*include[ \t]+"([^"]+)"[ \t]*$/gm;
const NAME = /^[A-Za-z_][A-Za-z0-9_]*$/;

/** A GLSL literal: integers as integers, other numbers with a decimal point (Python's repr digits). */
export function glslLiteral(value) {
  if (typeof value !== 'number' || !Number.isFinite(value)) {
    throw new TypeError(`not a finite number: ${value}`);
  }
  return Number.isInteger(value) ? String(value) : floatLiteral(value);
}

// Shortest round-trip digits like Python's repr (the two agree for plain decimals; defines from the manifest
// are integers).
function floatLiteral(v) {
  const text = String(v);
  return text.includes('.') || text.includes('e') ? text : `${text}.0`;
}

function formatValue(name, value) {
  if (typeof value === 'number') {
    return glslLiteral(value);
  }
  if (Array.isArray(value)) {
    return value.map((v) => formatValue(name, v)).join(', ');
  }
  if (typeof value === 'string') {
    if (value.includes('\n')) {
      throw new Error(`define ${name}: value must be one line`);
    }
    return value;
  }
  throw new TypeError(`define ${name}: unsupported value ${value}`);
}

export function formatDefine(name, value) {
  if (!NAME.test(name)) {
    throw new Error(`invalid define name ${name}`);
  }
  if (value === null || value === undefined || value === true) {
    return `#define ${name}`;
  }
  if (value === false) {
    throw new Error(`define ${name}: false is not a value; leave the define out instead`);
  }
  return `#define ${name} ${formatValue(name, value)}`;
}

export function header(target) {
  if (target === '330') {
    return '#version 330\n';
  }
  if (target === '300 es') {
    return '#version 300 es\nprecision highp float;\nprecision highp int;\n';
  }
  throw new Error(`unknown GLSL target ${target}`);
}

function expand(name, read, seen) {
  seen.add(name);
  let text = read(name);
  if (text === undefined || text === null) {
    throw new Error(`shader file ${name} not found`);
  }
  if (!text.endsWith('\n')) {
    text += '\n';
  }
  let out = '';
  let pos = 0;
  for (const match of text.matchAll(INCLUDE)) {
    out += text.slice(pos, match.index);
    const inc = match[1];
    if (!seen.has(inc)) {
      out += expand(inc, read, seen).replace(/\n+$/, '');
    }
    pos = match.index + match[0].length;
  }
  return out + text.slice(pos);
}

/**
 * The complete source of shader `name`.
 * @param {string} name file under web/shaders
 * @param {{target?: string, defines?: Object<string, *>, read: function(string): string}} options
 *   `defines` keep their insertion order; `read(name)` returns a file's text (see loadSources).
 */
export function build(name, { target = '300 es', defines = {}, read }) {
  const lines = Object.entries(defines).map(([k, v]) => `${formatDefine(k, v)}\n`);
  return header(target) + lines.join('') + expand(name, read, new Set());
}

/** Fetch shader files (with everything they include) from `base`; returns a read function for build(). */
export async function loadSources(names, base = 'shaders/', fetchImpl = fetch) {
  const files = new Map();
  const pending = [...names];
  while (pending.length) {
    const name = pending.pop();
    if (files.has(name)) {
      continue;
    }
    const resp = await fetchImpl(base + name);
    if (!resp.ok) {
      throw new Error(`shader ${name}: HTTP ${resp.status}`);
    }
    const text = await resp.text();
    files.set(name, text);
    for (const m of text.matchAll(INCLUDE)) {
      pending.push(m[1]);
    }
  }
  return (n) => files.get(n);
}
