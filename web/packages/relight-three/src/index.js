// relight-three: relight's engine exports in three.js r187 (README.md).
export { cubeChainTexture, decodePacked, loadCubeChain, mirrorColumns, parseCubeChain, RelightCubeChainLoader,
  SWAP, VK_FORMAT_B10G11R11_UFLOAT_PACK32, VK_FORMAT_E5B9G9R9_UFLOAT_PACK32, VK_FORMAT_R16G16B16A16_SFLOAT }
  from './environment.js';
export { CONVENTIONS, conventionScale, lightProbeFromSH, sphericalHarmonics, threeCoefficients }
  from './light_probe.js';
export { shaderSource, ShrmMaterial, TONEMAPS, withShaderAttributes } from './shrm_material.js';
