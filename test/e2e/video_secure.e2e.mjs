// The video socket in secure mode (docs/API.md "Video", "Security modes"): a page without a
// login, or with a bad token, is refused at the upgrade and gets no frame; an observer who
// logged in watches. ExUnit (test/e2e/external_test.exs) switches the test server to secure
// mode without anonymous observers, passes the observer's password in NEPTUNUS_E2E_LOGINS
// (JSON {name: password}) and the vehicle with the sim camera in E2E_VIDEO_VEHICLE.

import assert from "node:assert/strict";
import { request } from "node:http";
import { after, before, test } from "node:test";
import { BASE, CHROMIUM, WAIT_MS, reportCspViolations } from "./helpers.mjs";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const require = createRequire(join(dirname(fileURLToPath(import.meta.url)), "..", "..", "assets", "package.json"));
const LOGINS = JSON.parse(process.env.NEPTUNUS_E2E_LOGINS || "{}");
const VEHICLE = process.env.E2E_VIDEO_VEHICLE;
const OBSERVER = "e2e-olga";
const PATH = `/video/${encodeURIComponent(VEHICLE ?? "")}/websocket`;

let browser;
const pageProblems = [];

before(async () => {
  assert.ok(VEHICLE, "E2E_VIDEO_VEHICLE names a vehicle with a camera");
  assert.equal(typeof LOGINS[OBSERVER], "string", `NEPTUNUS_E2E_LOGINS has no password for ${OBSERVER}`);
  const session = await fetch(`${BASE}/api/session`).then((r) => r.json());
  assert.equal(session.mode, "secure", `the server must run in secure mode: ${JSON.stringify(session)}`);
  assert.equal(session.anonymous_observers, false);
  browser = await require("playwright-core").chromium.launch({ executablePath: CHROMIUM, args: ["--no-sandbox", "--disable-gpu", "--no-first-run"], timeout: 30000 });
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

/** A WebSocket upgrade request as a browser of this origin sends it: the status and body of a refusal. */
function upgrade(query) {
  return new Promise((resolve, reject) => {
    const url = new URL(`${BASE}${PATH}${query}`);
    const req = request(url, {
      headers: {
        Connection: "Upgrade",
        Upgrade: "websocket",
        Origin: BASE,
        "Sec-WebSocket-Version": "13",
        "Sec-WebSocket-Key": Buffer.from("neptunus-e2e-key").toString("base64"),
      },
    });
    req.on("upgrade", (res, socket) => {
      socket.destroy();
      resolve({ status: res.statusCode, body: "" });
    });
    req.on("response", (res) => {
      let body = "";
      res.on("data", (d) => (body += d));
      res.on("end", () => resolve({ status: res.statusCode, body }));
    });
    req.on("error", reject);
    req.setTimeout(WAIT_MS, () => req.destroy(new Error("no answer to the upgrade")));
    req.end();
  });
}

async function token() {
  const res = await fetch(`${BASE}/api/login`, {
    method: "POST",
    headers: { "content-type": "application/json", origin: BASE },
    body: JSON.stringify({ name: OBSERVER, password: LOGINS[OBSERVER] }),
  });
  assert.equal(res.status, 200, `login of ${OBSERVER}`);
  return (await res.json()).token;
}

test("the video socket refuses a page without a login, or with a bad token; an observer who logged in watches", { timeout: 60_000 }, async () => {
  // the refusals as the server gives them
  const none = await upgrade("?vsn=1");
  assert.equal(none.status, 401);
  assert.match(none.body, /login required/);
  const bad = await upgrade("?vsn=1&token=v1.not-a-token");
  assert.equal(bad.status, 401);
  const good = await upgrade(`?vsn=1&token=${encodeURIComponent(await token())}`);
  assert.equal(good.status, 101, "the observer's upgrade");

  // in Chromium: the socket without a login never opens and gets nothing; the observer's plays
  const context = await browser.newContext();
  await reportCspViolations(context);
  const page = await context.newPage();
  page.on("pageerror", (err) => pageProblems.push(`uncaught: ${err.message}`));
  try {
    await page.goto(`${BASE}/login.html`);
    const tryOpen = (query) =>
      page.evaluate(
        ({ url }) =>
          new Promise((resolve) => {
            const ws = new WebSocket(url);
            ws.binaryType = "arraybuffer";
            const seen = { opened: false, messages: 0, frames: 0 };
            ws.onopen = () => (seen.opened = true);
            ws.onmessage = (e) => {
              seen.messages += 1;
              if (e.data instanceof ArrayBuffer) seen.frames += 1;
              // an observer gets its frames: enough seen
              if (seen.frames >= 3) {
                ws.close();
                resolve(seen);
              }
            };
            ws.onclose = (e) => resolve({ ...seen, code: e.code });
          }),
        { url: `ws://${new URL(BASE).host}${PATH}${query}` },
      );
    const refused = await tryOpen("?vsn=1");
    assert.deepEqual(refused, { opened: false, messages: 0, frames: 0, code: 1006 }, "a page without a login");
    const observer = await tryOpen(`?vsn=1&token=${encodeURIComponent(await token())}`);
    assert.equal(observer.opened, true);
    assert.ok(observer.frames >= 3, "the observer's frames");
  } finally {
    await context.close();
  }
  // the refused socket is logged by the browser itself as a failed connection: nothing else
  assert.deepEqual(pageProblems.splice(0), []);
});
