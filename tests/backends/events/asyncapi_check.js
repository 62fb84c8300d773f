// Parse an AsyncAPI document with the official parser (@asyncapi/parser, which also validates every message
// payload whose schemaFormat it registers) and print one JSON line per diagnostic, then {"parsed": bool}.
//   NODE_PATH=<node_modules> node asyncapi_check.js FILE
"use strict";
const { Parser, fromFile } = require("@asyncapi/parser");

async function main() {
  const [file] = process.argv.slice(2);
  const { document, diagnostics } = await fromFile(new Parser(), file).parse();
  for (const d of diagnostics) {
    process.stdout.write(JSON.stringify({ severity: d.severity, code: d.code, message: d.message, path: d.path }) + "\n");
  }
  process.stdout.write(JSON.stringify({ parsed: document !== undefined }) + "\n");
}

main().catch((error) => {
  process.stderr.write(String(error && error.stack ? error.stack : error) + "\n");
  process.exit(1);
});
