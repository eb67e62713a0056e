#!/usr/bin/env node
// Decodes an (animated) PNG with UPNG.js and prints, as JSON, its size, frame count, plays, and
// each frame's rectangle, delay (ms), dispose and blend, and a hash of its RGBA8 pixels as shown
// (FNV-1a, 32 bits, over the composited frame). Exit status: 0 decoded, 2 could not read it.
'use strict';
const fs = require('fs');
const path = require('path');
const UPNG = require(path.join(__dirname, 'node_modules', 'upng-js'));

const file = process.argv[2];
if (!file) {
  console.error('usage: apng_frames.js FILE.png');
  process.exit(2);
}
let img;
try {
  const bytes = fs.readFileSync(file);
  img = UPNG.decode(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
} catch (e) {
  console.error(`${file}: ${e.message || e}`);
  process.exit(2);
}
const rgba = UPNG.toRGBA8(img);
function fnv1a(buf) {
  const b = new Uint8Array(buf);
  let h = 0x811c9dc5;
  for (let i = 0; i < b.length; i++) {
    h ^= b[i];
    h = Math.imul(h, 0x01000193) >>> 0;
  }
  return h >>> 0;
}
console.log(JSON.stringify({
  width: img.width,
  height: img.height,
  depth: img.depth,
  ctype: img.ctype,
  frames: img.frames.length,
  plays: img.tabs && img.tabs.acTL ? img.tabs.acTL.num_plays : null,
  frame: img.frames.map((f, i) => ({
    rect: [f.rect.x, f.rect.y, f.rect.width, f.rect.height],
    delay_ms: f.delay, dispose: f.dispose, blend: f.blend,
    fnv1a: fnv1a(rgba[i]),
  })),
}));
