// Types of @relight/three (src/index.js). three's own types come from @types/three.
import type { CompressedCubeTexture, LightProbe, LoadingManager, RawShaderMaterial, SphericalHarmonics3,
  BufferGeometry } from 'three';

export const VK_FORMAT_R16G16B16A16_SFLOAT: 97;
export const VK_FORMAT_B10G11R11_UFLOAT_PACK32: 122;
export const VK_FORMAT_E5B9G9R9_UFLOAT_PACK32: 123;
export type RelightVkFormat = 97 | 122 | 123;

/** One mip level of a chain: its face size and six float16 RGBA faces (GL order +X, -X, +Y, -Y, +Z, -Z). */
export interface CubeChainLevel {
  size: number;
  faces: Uint16Array[];
}

/** Metadata relight writes under `relight.*` keys: the level table, target, roughness mapping, SH9, sun. */
export interface CubeChainMetadata {
  writer?: string;
  target?: 'three' | 'filament' | 'gltf' | 'babylon';
  roughness_mapping?: 'quadratic' | 'linear' | 'log2';
  levels?: Array<Record<string, unknown>>;
  sh9?: Record<string, { quantity: string; coefficients: number[][] }>;
  sun?: Record<string, unknown> | null;
  [key: string]: unknown;
}

export interface CubeChain {
  size: number;
  levels: CubeChainLevel[];
  vkFormat: RelightVkFormat;
  metadata: CubeChainMetadata;
}

export type CubeChainTexture = CompressedCubeTexture & { isPMREMTexture: true };

export function decodePacked(value: number, vkFormat: RelightVkFormat): [number, number, number];
export function parseCubeChain(buffer: ArrayBuffer | Uint8Array): CubeChain;
export function mirrorColumns<T extends Uint16Array | Float32Array>(face: T, size: number): T;
export const SWAP: readonly number[];
/** A cube texture three r187 uses as a prefiltered environment (`isPMREMTexture`, maxLod = levels - 1). */
export function cubeChainTexture(chainOrBuffer: CubeChain | ArrayBuffer | Uint8Array): CubeChainTexture;
export function loadCubeChain(url: string | URL | Request, init?: RequestInit,
  fetchImpl?: typeof fetch): Promise<CubeChainTexture>;

export class RelightCubeChainLoader {
  constructor(manager?: LoadingManager);
  manager: LoadingManager | undefined;
  requestHeader: Record<string, string>;
  setRequestHeader(headers: Record<string, string>): this;
  load(url: string, onLoad: (texture: CubeChainTexture) => void, onProgress?: unknown,
    onError?: (err: unknown) => void): void;
  loadAsync(url: string): Promise<CubeChainTexture>;
  parse(buffer: ArrayBuffer | Uint8Array): CubeChainTexture;
}

export type SHConvention = 'three' | 'babylon' | 'gltf' | 'filament';
export const CONVENTIONS: readonly SHConvention[];
/** `relight sh --convention C` output, an `sh9` object, or any document holding `sh9`. */
export type SHDocument =
  | { convention: SHConvention; coefficients: number[][]; [key: string]: unknown }
  | { sh9: Record<string, { coefficients: number[][] }>; [key: string]: unknown }
  | Record<string, { coefficients: number[][] }>;
export function conventionScale(convention: SHConvention): number[];
export function threeCoefficients(doc: SHDocument): number[][];
export function sphericalHarmonics(doc: SHDocument): SphericalHarmonics3;
export function lightProbeFromSH(doc: SHDocument, intensity?: number): LightProbe;

export const TONEMAPS: { aces: number; reinhard: number; none: number };
export function shaderSource(name: string, defines?: Record<string, unknown>): string;
export function withShaderAttributes<G extends BufferGeometry>(geometry: G): G;

export interface ShrmMaterialOptions {
  /** The SHRM result's manifest (GET /shrms/{id}). */
  manifest: Record<string, unknown>;
  /** coefficients.bin: little-endian float16 RGB layers. */
  coefficients: ArrayBuffer | ArrayBufferView;
  mode?: 'near' | 'distant';
  output?: 'display' | 'linear';
  exposure?: number;
  tonemap?: 'aces' | 'reinhard' | 'none';
  rotation?: number;
}

export class ShrmMaterial extends RawShaderMaterial {
  constructor(options: ShrmMaterialOptions);
  readonly isShrmMaterial: true;
  mode: 'near' | 'distant';
  rotation: number;
  setRotation(angle: number): void;
}
