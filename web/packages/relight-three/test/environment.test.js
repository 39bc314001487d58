// The KTX2 adapter: container parsing (files written with the ktx-parse copy three vendors), packed-float
// decoding against hand-computed values, and the orientation rule checked with an independent OpenGL cube lookup
// (OpenGL 4.6 table 8.19): three reads the built texture at (-x, y, z), and must get the file's texel at d.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { DataUtils, HalfFloatType, RGBAFormat } from 'three';
import { createDefaultContainer, write } from 'three/addons/libs/ktx-parse.module.js';

import { cubeChainTexture, decodePacked, parseCubeChain, VK_FORMAT_B10G11R11_UFLOAT_PACK32,
  VK_FORMAT_E5B9G9R9_UFLOAT_PACK32, VK_FORMAT_R16G16B16A16_SFLOAT } from '../src/index.js';

/** A cube chain file: level i has faces of size >> i; texel value = f(face, level, row, col) in every channel. */
function chainFile(size, levels, vkFormat, texel, meta = {}) {
  const c = createDefaultContainer();
  c.vkFormat = vkFormat;
  c.typeSize = vkFormat === VK_FORMAT_R16G16B16A16_SFLOAT ? 2 : 4;
  c.pixelWidth = size;
  c.pixelHeight = size;
  c.faceCount = 6;
  c.levelCount = levels;
  c.dataFormatDescriptor[0].texelBlockDimension = [0, 0, 0, 0];
  c.dataFormatDescriptor[0].bytesPlane = [vkFormat === VK_FORMAT_R16G16B16A16_SFLOAT ? 8 : 4, 0, 0, 0, 0, 0, 0, 0];
  for (let lv = 0; lv < levels; lv += 1) {
    const s = Math.max(1, size >> lv);
    const words = vkFormat === VK_FORMAT_R16G16B16A16_SFLOAT ? new Uint16Array(6 * s * s * 4)
      : new Uint32Array(6 * s * s);
    for (let f = 0; f < 6; f += 1) {
      for (let r = 0; r < s; r += 1) {
        for (let col = 0; col < s; col += 1) {
          const t = (f * s + r) * s + col;
          const v = texel(f, lv, r, col);
          if (vkFormat === VK_FORMAT_R16G16B16A16_SFLOAT) {
            words.set([v, v + 1, v + 2, 1].map((x) => DataUtils.toHalfFloat(x)), 4 * t);
          } else {
            words[t] = v;
          }
        }
      }
    }
    const bytes = new Uint8Array(words.buffer);
    c.levels.push({ levelData: bytes, uncompressedByteLength: bytes.byteLength });
  }
  for (const [k, v] of Object.entries(meta)) {
    c.keyValue[`relight.${k}`] = new TextEncoder().encode(`${JSON.stringify(v)}\0`);
  }
  return write(c, { keepWriter: true });
}

test('parses the levels, faces and relight metadata', () => {
  const file = chainFile(4, 3, VK_FORMAT_R16G16B16A16_SFLOAT, (f, lv, r, c) => 100 * f + 10 * lv + r * 4 + c,
    { target: 'three', levels: [{ level: 0 }] });
  const chain = parseCubeChain(file);
  assert.equal(chain.size, 4);
  assert.deepEqual(chain.levels.map((l) => l.size), [4, 2, 1]);
  assert.deepEqual(chain.metadata.target, 'three');
  assert.deepEqual(chain.metadata.levels, [{ level: 0 }]);
  const face3 = chain.levels[1].faces[3];
  assert.equal(DataUtils.fromHalfFloat(face3[4 * (1 * 2 + 0)]), 300 + 10 + 4);  // row 1, column 0
  assert.equal(DataUtils.fromHalfFloat(face3[4 * (1 * 2 + 0) + 1]), 300 + 10 + 4 + 1);
});

test('the packed formats decode exactly', () => {
  // B10G11R11: R = 1.0 (e 15, m 0), G = 2.5 (e 16, m 0.25 * 64), B = 2^-14 * 3/32 (denormal m 3 of 5 bits)
  const b10 = (15 << 6) | ((16 << 6 | 16) << 11) | (3 << 22);
  assert.deepEqual(decodePacked(b10, VK_FORMAT_B10G11R11_UFLOAT_PACK32), [1, 2.5, 3 * 2 ** -19]);
  // E5B9G9R9: exponent 16 -> scale 2^(16 - 24); mantissas 256, 384, 1 -> 1, 1.5, 2^-8
  const e5 = 256 | (384 << 9) | (1 << 18) | (16 << 27);
  assert.deepEqual(decodePacked(e5 >>> 0, VK_FORMAT_E5B9G9R9_UFLOAT_PACK32), [1, 1.5, 2 ** -8]);
  const chain = parseCubeChain(chainFile(2, 2, VK_FORMAT_E5B9G9R9_UFLOAT_PACK32, () => e5 >>> 0));
  const face = chain.levels[0].faces[5];
  assert.deepEqual([...face.slice(0, 4)].map((h) => DataUtils.fromHalfFloat(h)), [1, 1.5, 2 ** -8, 1]);
});

/** OpenGL 4.6 table 8.19: direction -> [face, s, t]. */
function glFace([x, y, z]) {
  const ax = Math.abs(x);
  const ay = Math.abs(y);
  const az = Math.abs(z);
  let face; let sc; let tc; let ma;
  if (ax >= ay && ax >= az) {
    [face, sc, tc, ma] = x > 0 ? [0, -z, -y, ax] : [1, z, -y, ax];
  } else if (ay >= az) {
    [face, sc, tc, ma] = y > 0 ? [2, x, z, ay] : [3, x, -z, ay];
  } else {
    [face, sc, tc, ma] = z > 0 ? [4, x, -y, az] : [5, -x, -y, az];
  }
  return [face, (sc / ma + 1) / 2, (tc / ma + 1) / 2];
}

function nearest(face, s, t, size) {
  return [face, Math.min(size - 1, Math.floor(t * size)), Math.min(size - 1, Math.floor(s * size))];
}

test('three reads the radiance of direction d at d (no mirrored faces)', () => {
  const size = 8;
  const id = (f, lv, r, c) => 256 * f + 64 * lv + 8 * r + c;  // integers below 2048: exact in float16
  const tex = cubeChainTexture(chainFile(size, 2, VK_FORMAT_R16G16B16A16_SFLOAT, id));
  assert.equal(tex.isPMREMTexture, true);
  assert.equal(tex.isCubeTexture, true);  // so three flips x before the lookup (WebGLMaterials)
  assert.equal(tex.format, RGBAFormat);
  assert.equal(tex.type, HalfFloatType);
  assert.equal(tex.generateMipmaps, false);
  assert.equal(tex.image.length, 6);
  assert.equal(tex.image[0].mipmaps.length, 2);  // WebGLPrograms: maxLod = image[0].mipmaps.length - 1
  let checked = 0;
  for (let i = 0; i < 500; i += 1) {
    // directions at texel centres of the file (so nearest lookups are unambiguous)
    const f = i % 6;
    const r = (i * 7) % size;
    const c = (i * 3) % size;
    const a = (2 * (c + 0.5)) / size - 1;
    const b = (2 * (r + 0.5)) / size - 1;
    const d = [[1, -b, -a], [-1, -b, a], [a, 1, b], [a, -1, -b], [a, -b, 1], [-a, -b, -1]][f];
    const [f0, r0, c0] = nearest(...glFace(d), size);
    assert.deepEqual([f0, r0, c0], [f, r, c]);  // the file's texel at d (the inverse table agrees)
    const [f1, r1, c1] = nearest(...glFace([-d[0], d[1], d[2]]), size);
    const got = DataUtils.fromHalfFloat(tex.image[f1].mipmaps[0].data[4 * (r1 * size + c1)]);
    assert.equal(got, id(f, 0, r, c));
    checked += 1;
  }
  assert.equal(checked, 500);
});

test('refuses files that are not relight cube chains', () => {
  const c = createDefaultContainer();
  c.vkFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
  c.pixelWidth = 4;
  c.pixelHeight = 4;
  c.levels.push({ levelData: new Uint8Array(4 * 4 * 8), uncompressedByteLength: 4 * 4 * 8 });
  assert.throws(() => parseCubeChain(write(c)), /not a cube map/);
  assert.throws(() => parseCubeChain(chainFile(2, 1, 37, () => 0)), /unsupported vkFormat 37/);
  assert.throws(() => parseCubeChain(new Uint8Array(80)), /KTX 2.0 identifier/);
});
