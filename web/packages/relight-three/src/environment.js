// relight's KTX2 cube chains (`relight export --target three --format ktx2`, GET /envmaps/{id}/ibl) as the
// prefiltered environment three.js r187 reads: a cube texture whose mip `lod` holds the GGX split-sum lobe of
// roughness r with lod = maxLod r (2 - r), flagged `isPMREMTexture` so that three uses it as it is (no
// PMREMGenerator pass) for `scene.environment`, `material.envMap` and `scene.background`.
//
// Why an adapter: three r187's KTX2Loader turns an uncompressed 6-face file into a 2-D DataTexture (it builds
// cube textures only for transcoded or block-compressed formats), so it cannot load these files as cube maps.
// This module parses the container with the ktx-parse copy three itself vendors and builds the cube texture.
//
// Orientation: relight writes faces in the OpenGL order and orientation (+X, -X, +Y, -Y, +Z, -Z; the texel of
// face f, row i, column j has the GL direction of s = (j + 1/2) / N, t = (i + 1/2) / N; docs/conventions.md), in
// relight's world frame (+Y up, three.js' equirectUv). three samples a cube texture that is not a render target
// at (-x, y, z) (WebGLMaterials / WebGLBackground premultiply envMapRotation by diag(-1, 1, 1), the convention
// of cube images), so the texture built here holds face -X (mirrored left-right) as +X, +X as -X, and every
// other face mirrored left-right: three then reads the radiance of direction d at d.
//
// Texels: RGBA16F files are uploaded as they are; the packed unsigned floats (B10G11R11, E5B9G9R9) are decoded
// to float16 RGBA here (three's cube upload has no path for packed formats), exactly: every 10/11-bit float and
// every 9-bit mantissa times 2^(e - 24) is a float16 value.
import { CompressedCubeTexture, DataUtils, HalfFloatType, LinearFilter, LinearMipmapLinearFilter,
  LinearSRGBColorSpace, RGBAFormat } from 'three';
import { read } from 'three/addons/libs/ktx-parse.module.js';

export const VK_FORMAT_R16G16B16A16_SFLOAT = 97;
export const VK_FORMAT_B10G11R11_UFLOAT_PACK32 = 122;
export const VK_FORMAT_E5B9G9R9_UFLOAT_PACK32 = 123;
const FACE_NAMES = ['+X', '-X', '+Y', '-Y', '+Z', '-Z'];
const HALF_ONE = 0x3c00;

/** An unsigned float of `mbits` mantissa bits and a 5-bit exponent (bias 15), as a number. */
function unsignedFloat(bits, mbits) {
  const e = bits >>> mbits;
  const m = bits & ((1 << mbits) - 1);
  if (e === 0) {
    return m * 2 ** (-14 - mbits);
  }
  if (e === 31) {
    return m ? NaN : Infinity;
  }
  return (1 + m / (1 << mbits)) * 2 ** (e - 15);
}

/** One packed texel (Uint32) -> [r, g, b] numbers. */
export function decodePacked(value, vkFormat) {
  if (vkFormat === VK_FORMAT_B10G11R11_UFLOAT_PACK32) {
    return [unsignedFloat(value & 0x7ff, 6), unsignedFloat((value >>> 11) & 0x7ff, 6),
      unsignedFloat((value >>> 22) & 0x3ff, 5)];
  }
  if (vkFormat === VK_FORMAT_E5B9G9R9_UFLOAT_PACK32) {
    const scale = 2 ** ((value >>> 27) - 15 - 9);
    return [(value & 0x1ff) * scale, ((value >>> 9) & 0x1ff) * scale, ((value >>> 18) & 0x1ff) * scale];
  }
  throw new Error(`relight-three: not a packed format: vkFormat ${vkFormat}`);
}

function metadata(container) {
  const out = {};
  const text = new TextDecoder();
  for (const [key, value] of Object.entries(container.keyValue || {})) {
    if (key.startsWith('relight.')) {
      const bytes = typeof value === 'string' ? value : text.decode(value);
      out[key.slice('relight.'.length)] = JSON.parse(bytes.replace(/\0+$/, ''));
    } else if (key === 'KTXwriter') {
      out.writer = typeof value === 'string' ? value : text.decode(value).replace(/\0+$/, '');
    }
  }
  return out;
}

/**
 * Parse a relight KTX2 cube chain: `{ size, levels: [{ size, faces: [Uint16Array x 6] }], vkFormat, metadata }`,
 * faces as stored (OpenGL order and orientation), texels float16 RGBA (packed formats decoded).
 */
export function parseCubeChain(buffer) {
  const bytes = buffer instanceof Uint8Array ? buffer : new Uint8Array(buffer);
  const c = read(bytes);
  if (c.faceCount !== 6 || c.pixelWidth !== c.pixelHeight || c.pixelDepth !== 0 || c.layerCount > 1) {
    throw new Error(`relight-three: not a cube map (faces ${c.faceCount}, ${c.pixelWidth} x ${c.pixelHeight}, `
      + `depth ${c.pixelDepth}, layers ${c.layerCount})`);
  }
  if (c.supercompressionScheme !== 0) {
    throw new Error(`relight-three: supercompression ${c.supercompressionScheme} is not supported`);
  }
  const fmt = c.vkFormat;
  if (![VK_FORMAT_R16G16B16A16_SFLOAT, VK_FORMAT_B10G11R11_UFLOAT_PACK32, VK_FORMAT_E5B9G9R9_UFLOAT_PACK32]
    .includes(fmt)) {
    throw new Error(`relight-three: unsupported vkFormat ${fmt} (RGBA16F, B10G11R11 or E5B9G9R9)`);
  }
  const levels = c.levels.map((level, i) => {
    const size = Math.max(1, c.pixelWidth >> i);
    const texels = size * size;
    const data = level.levelData;
    const texelBytes = fmt === VK_FORMAT_R16G16B16A16_SFLOAT ? 8 : 4;
    if (data.byteLength !== 6 * texels * texelBytes) {
      throw new Error(`relight-three: level ${i} holds ${data.byteLength} bytes, expected ${6 * texels * texelBytes}`);
    }
    const faces = [];
    for (let f = 0; f < 6; f += 1) {
      const start = data.byteOffset + f * texels * texelBytes;
      if (fmt === VK_FORMAT_R16G16B16A16_SFLOAT) {
        faces.push(new Uint16Array(data.buffer.slice(start, start + texels * 8)));
      } else {
        const packed = new Uint32Array(data.buffer.slice(start, start + texels * 4));
        const half = new Uint16Array(texels * 4);
        for (let t = 0; t < texels; t += 1) {
          const rgb = decodePacked(packed[t], fmt);
          half[4 * t] = DataUtils.toHalfFloat(rgb[0]);
          half[4 * t + 1] = DataUtils.toHalfFloat(rgb[1]);
          half[4 * t + 2] = DataUtils.toHalfFloat(rgb[2]);
          half[4 * t + 3] = HALF_ONE;
        }
        faces.push(half);
      }
    }
    return { size, faces };
  });
  return { size: c.pixelWidth, levels, vkFormat: fmt, metadata: metadata(c) };
}

/** A face (RGBA, size x size) with its columns reversed. */
export function mirrorColumns(face, size) {
  const out = new face.constructor(face.length);
  for (let row = 0; row < size; row += 1) {
    for (let col = 0; col < size; col += 1) {
      const src = 4 * (row * size + col);
      const dst = 4 * (row * size + size - 1 - col);
      out[dst] = face[src];
      out[dst + 1] = face[src + 1];
      out[dst + 2] = face[src + 2];
      out[dst + 3] = face[src + 3];
    }
  }
  return out;
}

/**
 * The six faces three.js must hold so that its flipped lookup (module comment) reads direction d at d: face k
 * of the result is the mirrored face SWAP[k] of the file.
 */
export const SWAP = [1, 0, 2, 3, 4, 5];

/**
 * A texture three.js r187 uses as a prefiltered environment (`isPMREMTexture`), from a parsed chain or the
 * file's bytes. `maxLod` three derives from it is `levels - 1`, the chain's own last level.
 */
export function cubeChainTexture(chainOrBuffer) {
  const chain = chainOrBuffer && chainOrBuffer.levels ? chainOrBuffer : parseCubeChain(chainOrBuffer);
  const faces = SWAP.map((src) => ({
    width: chain.size,
    height: chain.size,
    mipmaps: chain.levels.map((lv) => ({ data: mirrorColumns(lv.faces[src], lv.size), width: lv.size,
      height: lv.size })),
  }));
  const texture = new CompressedCubeTexture(faces, RGBAFormat, HalfFloatType);
  texture.name = 'relight cube chain';
  texture.minFilter = chain.levels.length > 1 ? LinearMipmapLinearFilter : LinearFilter;
  texture.magFilter = LinearFilter;
  texture.generateMipmaps = false;
  texture.colorSpace = LinearSRGBColorSpace;
  texture.isPMREMTexture = true;
  texture.userData.relight = { ...chain.metadata, faceOrder: FACE_NAMES, vkFormat: chain.vkFormat };
  texture.needsUpdate = true;
  return texture;
}

/** Fetch a chain (URL or Request; `init` as fetch's) and build its texture. */
export async function loadCubeChain(url, init = undefined, fetchImpl = globalThis.fetch) {
  const resp = await fetchImpl(url, init);
  if (!resp.ok) {
    throw new Error(`relight-three: ${url}: HTTP ${resp.status}`);
  }
  return cubeChainTexture(new Uint8Array(await resp.arrayBuffer()));
}

/** A three.js Loader-style wrapper: `new RelightKTX2Loader().load(url, onLoad, undefined, onError)`. */
export class RelightCubeChainLoader {
  constructor(manager = undefined) {
    this.manager = manager;
    this.requestHeader = {};
  }

  setRequestHeader(headers) {
    this.requestHeader = headers;
    return this;
  }

  loadAsync(url) {
    return loadCubeChain(url, { headers: this.requestHeader });
  }

  load(url, onLoad, onProgress, onError) {
    this.loadAsync(url).then(onLoad, (err) => {
      if (onError) {
        onError(err);
      } else {
        console.error(err);
      }
    });
  }

  parse(buffer) {
    return cubeChainTexture(buffer);
  }
}
