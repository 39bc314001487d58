// Display transform, identical to relight.envmap.tonemap (the server's PNG previews) and web/src/tonemap.js:
// x = max(rgb, 0) 2^exposure, then TONEMAP_ACES (Narkowicz 2016's fit), TONEMAP_REINHARD (x / (1 + x)) or
// TONEMAP_NONE (clamp), then the sRGB OETF (IEC 61966-2-1). The canvas receives the encoded values.

uniform float u_exposure;  // stops
uniform int u_tonemap;     // TONEMAP_ACES, TONEMAP_REINHARD or TONEMAP_NONE

vec3 aces_narkowicz(vec3 x) {
    return x * (ACES_A * x + ACES_B) / (x * (ACES_C * x + ACES_D) + ACES_E);
}

vec3 srgb_oetf(vec3 c) {
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

vec3 tonemap_display(vec3 rgb) {
    vec3 x = max(rgb, vec3(0.0)) * exp2(u_exposure);
    vec3 y;
    if (u_tonemap == TONEMAP_ACES) {
        y = aces_narkowicz(x);
    } else if (u_tonemap == TONEMAP_REINHARD) {
        y = x / (1.0 + x);
    } else {
        y = x;
    }
    return srgb_oetf(clamp(y, 0.0, 1.0));
}
