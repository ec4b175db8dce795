/**
 * Developer page entry (`/dev.html?vehicle=ID`): plots of every telemetry series and the logger.
 * It watches only; it never asks for control.
 */

import { render } from "preact";
import { DevApp } from "./app";
import { DevController } from "./controller";

function main(): void {
  const root = document.getElementById("app");
  if (!root) throw new Error("developer page: #app is missing from dev.html");
  const controller = new DevController(new URLSearchParams(window.location.search));
  render(<DevApp controller={controller} />, root);
  controller.start().catch((err: unknown) => console.error("neptunus:", err));
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", main, { once: true });
} else {
  main();
}
