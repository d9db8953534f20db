// Builds the viewer's bundles described in bundles.json with esbuild's JS API.
//
//   node viewer/build.mjs            build every bundle
//   node viewer/build.mjs --outputs  print the bundles' paths (relative to the current
//                                    folder), one a line, without building
//
// npm run --prefix viewer build, the Makefile and setup.py's build hook call this
// script, so the entry points, outputs and options live in one place (bundles.json).
import { readFileSync } from "node:fs";
import { dirname, relative, resolve } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const spec = JSON.parse(readFileSync(resolve(here, "bundles.json"), "utf8"));
const bundles = spec.bundles.map((b) => ({
  entry: resolve(here, b.entry),
  outfile: resolve(here, b.outfile),
}));

const args = process.argv.slice(2);
if (args.length === 1 && args[0] === "--outputs") {
  for (const b of bundles) console.log(relative(process.cwd(), b.outfile));
} else if (args.length > 0) {
  console.error(`usage: node build.mjs [--outputs]; got ${args.join(" ")}`);
  process.exit(2);
} else {
  // imported here, so that --outputs works before npm ci has installed esbuild
  let esbuild;
  try {
    esbuild = await import("esbuild");
  } catch (err) {
    console.error(`viewer/build.mjs: esbuild is not installed (${err.code ?? err.message}); ` +
      "run npm ci --prefix viewer first");
    process.exit(1);
  }
  try {
    await Promise.all(bundles.map((b) => esbuild.build({
      ...spec.options, entryPoints: [b.entry], outfile: b.outfile, absWorkingDir: here,
    })));
  } catch {
    process.exit(1);  // esbuild has printed the errors (logLevel)
  }
}
