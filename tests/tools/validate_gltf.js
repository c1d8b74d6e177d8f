// Validate a glTF 2.0 file with the Khronos glTF validator (npm package `gltf-validator`) and
// print its report as JSON on stdout: {"numErrors", "numWarnings", "numInfos", "messages": [...]}.
// Usage: NODE_PATH=<folder holding node_modules/gltf-validator's parent> node validate_gltf.js FILE
// Exit 0 whenever a report was made (the caller reads the counts), 3 when none could be made.
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

const file = process.argv[2];
const bytes = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    // External resources are resolved beside the file (a .gltf may reference a .bin).
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  })
  .then((report) => {
    const i = report.issues;
    process.stdout.write(JSON.stringify({
      numErrors: i.numErrors, numWarnings: i.numWarnings, numInfos: i.numInfos,
      messages: i.messages,
    }) + "\n");
  })
  .catch((err) => {
    process.stderr.write(String(err) + "\n");
    process.exit(3);
  });
