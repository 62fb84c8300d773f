// The Thingweb Playground core validator (npm @thing-description-playground/core) on one TD file:
// `node playground_validate.js TD.json` prints {"report": ..., "details": ..., "log": [...]} as JSON.
// NODE_PATH must name the node_modules it is installed in (.ci/setup-wot.sh: .cache/wot/node_modules).
// JSON-LD expansion is off: it fetches the TD's @context documents from the web, which tests cannot reach;
// linked-TM checks are off: the TD links no Thing Model.
"use strict";
const fs = require("fs");
const { tdValidator } = require("@thing-description-playground/core");

const text = fs.readFileSync(process.argv[2], "utf8");
const log = [];
tdValidator(text, (line) => log.push(String(line)), { checkDefaults: true, checkJsonLd: false, checkTmConformance: false })
  .then((result) => {
    process.stdout.write(JSON.stringify({ report: result.report, details: result.details, log }) + "\n");
  })
  .catch((err) => {
    process.stderr.write(String(err) + "\n");
    process.exit(1);
  });
