/**
 * Operator page entry: builds the controller (connection, helm, inputs, safety) and renders the
 * Preact view into #app. Query parameters: `vehicle` (default: the first vehicle of the fleet),
 * `name` (display name in local mode; default: the server's `guest-XXXX`).
 */

import { render } from "preact";
import { App } from "./app";
import { OperatorController } from "./controller";

function main(): void {
  const root = document.getElementById("app");
  if (!root) throw new Error("operator page: #app is missing from index.html");
  const controller = new OperatorController(new URLSearchParams(window.location.search));
  render(<App controller={controller} />, root);
  controller.start().catch((err: unknown) => console.error("neptunus:", err));
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", main, { once: true });
} else {
  main();
}
