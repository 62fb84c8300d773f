// Generate data models from an AsyncAPI document with AsyncAPI Modelina, as `asyncapi generate models
// python|typescript FILE` does (@asyncapi/cli 6.2 runs Modelina 5.10 on the file): one JSON line per model
// ({name, code}), then {"generated": N}. Exits 1 with the error on stderr when Modelina refuses the document.
//   NODE_PATH=<node_modules> node modelina_models.js python|typescript FILE
"use strict";
const { pathToFileURL } = require("url");
const { PythonGenerator, TypeScriptGenerator } = require("@asyncapi/modelina");

async function main() {
  const [language, file] = process.argv.slice(2);
  const generator = language === "python" ? new PythonGenerator() : new TypeScriptGenerator();
  const models = await generator.generate(pathToFileURL(file).href);
  for (const model of models) {
    process.stdout.write(JSON.stringify({ name: model.modelName, code: model.result }) + "\n");
  }
  process.stdout.write(JSON.stringify({ generated: models.length }) + "\n");
}

main().catch((error) => {
  process.stderr.write(String(error && error.stack ? error.stack : error) + "\n");
  process.exit(1);
});
