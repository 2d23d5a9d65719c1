// The scene's local NED tangent plane <-> WGS84, the same exact mapping as
// asvtwin.geo.LocalFrame (ellipsoid surface point -> ECEF -> rotate into NED; the inverse
// moves the plane point along the origin's down axis onto the ellipsoid, closed form).
// The browser test checks this port against the Python one to 1e-8 deg.
const A = 6378137.0;
const F = 1 / 298.257223563;
const B = A * (1 - F);
const E2 = F * (2 - F);
const D2R = Math.PI / 180;

function ecef(latRad, lonRad) {
  const s = Math.sin(latRad), c = Math.cos(latRad);
  const n = A / Math.sqrt(1 - E2 * s * s);
  return [n * c * Math.cos(lonRad), n * c * Math.sin(lonRad), n * (1 - E2) * s];
}

export class LocalFrame {
  constructor(lat0Deg, lon0Deg) {
    this.lat0 = lat0Deg;
    this.lon0 = lon0Deg;
    const phi = lat0Deg * D2R, lam = lon0Deg * D2R;
    this.p0 = ecef(phi, lam);
    const sp = Math.sin(phi), cp = Math.cos(phi), sl = Math.sin(lam), cl = Math.cos(lam);
    this.rn = [-sp * cl, -sp * sl, cp];
    this.re = [-sl, cl, 0];
    this.rd = [-cp * cl, -cp * sl, -sp];
  }

  // [north_m, east_m] -> [lon_deg, lat_deg] (GeoJSON order)
  toLonLat(n, e) {
    const { p0, rn, re, rd } = this;
    const px = (p0[0] + rn[0] * n + re[0] * e) / A;
    const py = (p0[1] + rn[1] * n + re[1] * e) / A;
    const pz = (p0[2] + rn[2] * n + re[2] * e) / A;
    const k = (A / B) ** 2;
    const qa = rd[0] ** 2 + rd[1] ** 2 + k * rd[2] ** 2;
    const qb = px * rd[0] + py * rd[1] + k * pz * rd[2];
    const qc = px * px + py * py + k * pz * pz - 1;
    const disc = Math.sqrt(Math.max(qb * qb - qa * qc, 0));
    const d = -qc / (qb + (qb >= 0 ? disc : -disc));
    const x = px + d * rd[0], y = py + d * rd[1], z = pz + d * rd[2];
    const lat = Math.atan2(z, (1 - E2) * Math.hypot(x, y));
    const lon = Math.atan2(y, x);
    return [((lon / D2R + 180) % 360 + 360) % 360 - 180, lat / D2R];
  }

  // [lon_deg, lat_deg] -> [north_m, east_m]
  toNed(lon, lat) {
    const [x, y, z] = ecef(lat * D2R, lon * D2R);
    const dx = x - this.p0[0], dy = y - this.p0[1], dz = z - this.p0[2];
    return [this.rn[0] * dx + this.rn[1] * dy + this.rn[2] * dz, this.re[0] * dx + this.re[1] * dy];
  }

  ring(points) { return points.map((p) => this.toLonLat(p[0], p[1])); }
}

// Range [m] and true bearing [deg, 0..360) from a to b (NED).
export function rangeBearing(a, b) {
  const dn = b[0] - a[0], de = b[1] - a[1];
  return [Math.hypot(dn, de), ((Math.atan2(de, dn) / D2R) + 360) % 360];
}

// CPA [m] and TCPA [s] of a target (p, v) relative to own ship (p0, v0); null when they
// do not close (TCPA < 0 or no relative motion).
export function cpaTcpa(p0, v0, p, v) {
  const dx = p[0] - p0[0], dy = p[1] - p0[1];
  const vx = v[0] - v0[0], vy = v[1] - v0[1];
  const vv = vx * vx + vy * vy;
  if (vv < 1e-9) return [Math.hypot(dx, dy), null];
  const t = -(dx * vx + dy * vy) / vv;
  if (t < 0) return [null, null];
  return [Math.hypot(dx + vx * t, dy + vy * t), t];
}

export const KN = 1852 / 3600;
export const NM = 1852;
export const deg = (rad) => (((rad / D2R) % 360) + 360) % 360;
export const rad = (d) => d * D2R;
