#!/usr/bin/env node
// Runs the Khronos glTF validator on one .gltf/.glb file and prints its JSON report.
// Exit status: 0 no errors, 1 errors, 2 the validator could not read the file.
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require(path.join(__dirname, 'node_modules', 'gltf-validator'));

const file = process.argv[2];
if (!file) {
  console.error('usage: validate.js FILE.gltf|FILE.glb');
  process.exit(2);
}
let data;
try {
  data = new Uint8Array(fs.readFileSync(file));
} catch (e) {
  console.error(`${file}: ${e.message}`);
  process.exit(2);
}
validator.validateBytes(data, {
  uri: path.basename(file),
  maxIssues: 200,
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    try {
      resolve(new Uint8Array(fs.readFileSync(path.join(path.dirname(file), decodeURIComponent(uri)))));
    } catch (e) {
      reject(e.toString());
    }
  }),
}).then((report) => {
  console.log(JSON.stringify(report));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
}).catch((e) => {
  console.error(`${file}: ${e}`);
  process.exit(2);
});
