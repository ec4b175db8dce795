// Builds the browser assets into ../priv/static (served by the Neptunus endpoint):
//   src/operator/main.tsx  → priv/static/assets/app.js (+ .map), bundled, minified, es2020
//   src/developer/main.tsx → priv/static/assets/dev.js (+ .map)
//   src/login/main.ts      → priv/static/assets/login.js (+ .map)
//   src/camera/main.tsx    → priv/static/assets/camera.js (+ .map)
//   static/index.html      → priv/static/index.html
//   static/dev.html        → priv/static/dev.html
//   static/login.html      → priv/static/login.html
//   static/camera.html     → priv/static/camera.html
//   static/app.css         → priv/static/assets/app.css
//   uplot's uPlot.min.css  → priv/static/assets/uplot.css
// TSX uses Preact's automatic JSX runtime (tsconfig.json: jsx react-jsx, jsxImportSource preact).
// Usage: node build.mjs [--watch]     (npm run build)
import { copyFile, mkdir } from "node:fs/promises";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import * as esbuild from "esbuild";

const here = dirname(fileURLToPath(import.meta.url));
const outRoot = join(here, "..", "priv", "static");
const outAssets = join(outRoot, "assets");
const watch = process.argv.includes("--watch");

const copies = [
  [join(here, "static", "index.html"), join(outRoot, "index.html")],
  [join(here, "static", "login.html"), join(outRoot, "login.html")],
  [join(here, "static", "dev.html"), join(outRoot, "dev.html")],
  [join(here, "static", "camera.html"), join(outRoot, "camera.html")],
  [join(here, "static", "replay.html"), join(outRoot, "replay.html")],
  [join(here, "static", "app.css"), join(outAssets, "app.css")],
  [join(here, "node_modules", "uplot", "dist", "uPlot.min.css"), join(outAssets, "uplot.css")],
];

async function copyStatic() {
  await mkdir(outAssets, { recursive: true });
  await Promise.all(copies.map(([from, to]) => copyFile(from, to)));
}

/** @type {import("esbuild").BuildOptions} */
const options = {
  absWorkingDir: here,
  entryPoints: {
    app: join(here, "src", "operator", "main.tsx"),
    dev: join(here, "src", "developer", "main.tsx"),
    login: join(here, "src", "login", "main.ts"),
    camera: join(here, "src", "camera", "main.tsx"),
    replay: join(here, "src", "replay", "main.tsx"),
  },
  outdir: outAssets,
  bundle: true,
  format: "iife",
  platform: "browser",
  target: "es2020",
  minify: true,
  sourcemap: true,
  logLevel: "info",
};

try {
  await copyStatic();
  if (watch) {
    const ctx = await esbuild.context({
      ...options,
      plugins: [{ name: "copy-static", setup: (b) => b.onEnd(() => copyStatic()) }],
    });
    await ctx.watch();
    console.log("watching src/ (static/ is copied on every rebuild)");
  } else {
    await esbuild.build(options);
  }
} catch (err) {
  // esbuild has already printed the errors it found
  if (!(err && typeof err === "object" && "errors" in err)) console.error(err);
  process.exitCode = 1;
}
