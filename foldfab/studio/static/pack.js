// The studio's binary answers (foldfab.studio.api.pack): magic, header length, JSON header,
// 8-byte aligned little-endian arrays, read without parsing.

const TYPES = { f4: Float32Array, f8: Float64Array, u4: Uint32Array, u1: Uint8Array };

/** {header, arrays} of a binary answer; the arrays are views on ``buffer``. */
export function unpack(buffer) {
  const magic = new TextDecoder().decode(new Uint8Array(buffer, 0, 4));
  if (magic !== "FFS1") throw new Error("not a studio design");
  const length = new DataView(buffer).getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, length)));
  const base = 8 + length;
  const arrays = {};
  for (const [name, m] of Object.entries(header.arrays)) {
    const count = m.shape.reduce((x, y) => x * y, 1);
    arrays[name] = new TYPES[m.dtype](buffer, base + m.offset, count);
  }
  return { header, arrays };
}
