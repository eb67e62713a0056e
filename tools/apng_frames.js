#!/usr/bin/env node
// Decodes an (animated) PNG with UPNG.js and prints, as JSON, its size, frame count (1 for a still
// PNG), plays, and each frame's rectangle, delay (ms), dispose and blend (animated only), and a hash
// of its RGBA8 pixels as shown
// (FNV-1a, 32 bits, over the composited frame); with --count R,G,B, also how many of each frame's
// pixels have exactly that colour, in all and in its left half. Exit status: 0 decoded, 2 could not
// read it.
'use strict';
const fs = require('fs');
const path = require('path');
const UPNG = require(path.join(__dirname, 'node_modules', 'upng-js'));

const args = process.argv.slice(2);
let count = null;
const at = args.indexOf('--count');
if (at >= 0) {
  count = (args[at + 1] || '').split(',').map(Number);
  args.splice(at, 2);
  if (count.length !== 3 || count.some((v) => !(v >= 0 && v <= 255))) {
    console.error('--count: expected R,G,B from 0 to 255');
    process.exit(2);
  }
}
const file = args[0];
if (!file) {
  console.error('usage: apng_frames.js [--count R,G,B] FILE.png');
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
function counted(buf) {
  const b = new Uint8Array(buf);
  let all = 0, left = 0;
  for (let i = 0; i < img.width * img.height; i++) {
    if (b[4 * i] === count[0] && b[4 * i + 1] === count[1] && b[4 * i + 2] === count[2]) {
      all++;
      if (i % img.width < img.width / 2) left++;
    }
  }
  return { count: all, count_left: left };
}
console.log(JSON.stringify({
  width: img.width,
  height: img.height,
  depth: img.depth,
  ctype: img.ctype,
  animated: img.frames.length > 0,
  frames: rgba.length,  // a still PNG: one
  plays: img.tabs && img.tabs.acTL ? img.tabs.acTL.num_plays : null,
  frame: rgba.map((buf, i) => {
    const f = img.frames[i];
    return {
      ...(f ? { rect: [f.rect.x, f.rect.y, f.rect.width, f.rect.height], delay_ms: f.delay, dispose: f.dispose, blend: f.blend } : {}),
      fnv1a: fnv1a(buf),
      ...(count ? counted(buf) : {}),
    };
  }),
}));
