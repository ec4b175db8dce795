// Browser test of the developer page (/dev.html): plots (uPlot) and the logger, against a
// running Neptunus server, at 1920×1080 and 1024×768. See helpers.mjs for the set-up.

import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { after, before, test } from "node:test";
import {
  DESKTOP,
  TABLET,
  TEST_MS,
  WAIT_MS,
  assertNoPageProblems,
  launch,
  open,
  screenshot,
  takeHelm,
  until,
  waitTelemetry,
} from "./helpers.mjs";

let browser;

before(async () => {
  browser = await launch();
});

after(async () => {
  await browser?.close().catch(() => undefined);
});

const plots = (page) => page.locator('[data-testid="plot"]');
const samples = async (page) => Number(await page.locator("#buffer").getAttribute("data-samples"));
const seriesOf = (page) => plots(page).evaluateAll((els) => els.map((e) => e.getAttribute("data-series")));
const plotsStatus = (page) => page.locator("#plots-status").getAttribute("data-state");

const DEFAULT_SERIES = [
  "measurement.depth,autopilot.depth.setpoint,estimate.depth",
  "measurement.heading,autopilot.heading.setpoint,estimate.heading",
  "thrusters.port,thrusters.vertical,thrusters.starboard",
  "measurement.voltage",
  "measurement.current",
  // the test server's simulated vehicle has a position source (its simulated DVL and USBL)
  "position.north,position.east",
  "position.std_north,position.std_east",
];

/** Back to the default plots (this server's local user keeps them), then none on the page. */
async function noPlots(page) {
  await page.locator("#reset-plots").click();
  await until(() => plotsStatus(page), (s) => s === "default", WAIT_MS, "default plots");
  await page.locator("#remove-plots").click();
  await until(() => plots(page).count(), (n) => n === 0, WAIT_MS, "no plots");
}

test("developer page: opens with the default plots (depth, heading, thrusters, voltage, current, position), kept per user on the server; telemetry age", { timeout: TEST_MS }, async () => {
  const dev = await open(browser, { ...DESKTOP, name: "e2e-dev-defaults", path: "/dev.html" });
  try {
    const { page } = dev;
    await page.locator("#reset-plots").click();
    await until(() => plotsStatus(page), (s) => s === "default", WAIT_MS, "default plots");
    // with position once the vehicle's telemetry says it has a position source
    await until(() => seriesOf(page), (s) => JSON.stringify(s) === JSON.stringify(DEFAULT_SERIES), WAIT_MS, "the default plots, with position");
    await until(() => samples(page), (n) => n > 5, WAIT_MS, "recorded samples");
    await page.locator('[data-testid="plot"] canvas').nth(4).waitFor();
    // the estimate is drawn next to the measurement: the legend has a value for it on hover
    await plots(page).first().locator(".u-over").hover();
    await until(
      async () => (await plots(page).first().locator(".u-legend .u-value").nth(3).textContent()) ?? "",
      (t) => /\d/.test(t),
      WAIT_MS,
      "the depth estimate's value in the legend",
    );
    // telemetry age, as on the operator page
    await page.locator('#telemetry-age[data-state="live"]').waitFor();
    assert.equal(await page.locator("#telemetry-age").textContent(), "live");

    // a change is saved for this user: another device opens with it
    await plots(page).nth(3).locator('[data-testid="remove-plot"]').click();
    await plots(page).first().locator("select.add-series").selectOption("measurement.roll");
    await until(() => plotsStatus(page), (s) => s === "saved", WAIT_MS, "plots saved");
    const changed = [DEFAULT_SERIES[0] + ",measurement.roll", ...DEFAULT_SERIES.slice(1, 3), ...DEFAULT_SERIES.slice(4)];
    assert.deepEqual(await seriesOf(page), changed);
    const other = await open(browser, { ...TABLET, name: "e2e-dev-defaults-2", path: "/dev.html" });
    try {
      await until(() => plotsStatus(other.page), (s) => s === "stored", WAIT_MS, "the stored plots");
      assert.deepEqual(await seriesOf(other.page), changed);
    } finally {
      await other.context.close();
    }

    // reset to defaults: here and on the next device
    await page.locator("#reset-plots").click();
    await until(() => plotsStatus(page), (s) => s === "default", WAIT_MS, "default plots again");
    assert.deepEqual(await seriesOf(page), DEFAULT_SERIES);
    const third = await open(browser, { ...DESKTOP, name: "e2e-dev-defaults-3", path: "/dev.html" });
    try {
      await until(() => plotsStatus(third.page), (s) => s === "default", WAIT_MS, "the default plots");
      await until(() => seriesOf(third.page), (s) => JSON.stringify(s) === JSON.stringify(DEFAULT_SERIES), WAIT_MS, "the default plots, with position");
    } finally {
      await third.context.close();
    }
    assertNoPageProblems();
  } finally {
    await dev.context.close();
  }
});

test("developer page: add 3 plots, reset graphs, remove; CSV; logger categories (1920×1080 and 1024×768)", { timeout: TEST_MS }, async () => {
  const dev = await open(browser, { ...DESKTOP, name: "e2e-dev", path: "/dev.html" });
  const pilot = await open(browser, { ...TABLET, name: "e2e-dev-pilot" });
  try {
    const { page } = dev;
    await waitTelemetry(pilot.page);
    await page.locator('[data-testid="log-topic"][data-state="joined"]').waitFor();
    await until(() => samples(page), (n) => n > 5, WAIT_MS, "recorded samples");
    assert.match((await page.locator("#buffer").textContent()) ?? "", /12,000 samples/);
    await noPlots(page);

    // plots: add three, each with its own series and a uPlot canvas
    for (let i = 1; i <= 3; i++) {
      await page.locator("#add-plot").click();
      await until(() => plots(page).count(), (n) => n === i, WAIT_MS, `${i} plots`);
    }
    await page.locator('[data-testid="plot"] canvas').nth(2).waitFor();
    const series = await plots(page).evaluateAll((els) => els.map((e) => e.getAttribute("data-series")));
    assert.equal(series[0], "measurement.depth");
    assert.ok(series.every((s) => s && s.length > 0), `every plot has series: ${series}`);
    // overlay one more series on the first plot from the picker
    await plots(page).first().locator("select.add-series").selectOption("measurement.heading");
    await until(async () => plots(page).first().getAttribute("data-series"), (s) => s === "measurement.depth,measurement.heading", WAIT_MS, "two series overlaid");
    // values under the cursor in the legend
    await plots(page).first().locator(".u-over").hover();
    await until(
      async () => (await plots(page).first().locator(".u-legend .u-value").nth(1).textContent()) ?? "",
      (t) => /\d/.test(t),
      WAIT_MS,
      "a value in the legend on hover",
    );

    // CSV of the buffer
    const [download] = await Promise.all([page.waitForEvent("download"), page.locator("#download-csv").click()]);
    const csv = readFileSync(await download.path(), "utf8").split("\n");
    assert.match(csv[0], /^time,measurement\.depth,measurement\.roll,/);
    assert.ok(csv.length > 5, "CSV rows");

    // reset graphs: the data goes, the plots stay
    await page.locator("#reset-graphs").click();
    assert.equal(await plots(page).count(), 3);
    assert.ok((await samples(page)) < 10, "reset kept the data");
    await until(() => samples(page), (n) => n > 0, WAIT_MS, "recording goes on after a reset");

    // remove one, then all
    await plots(page).nth(1).locator('[data-testid="remove-plot"]').click();
    await until(() => plots(page).count(), (n) => n === 2, WAIT_MS, "2 plots");
    await page.locator("#add-plot").click();
    await until(() => plots(page).count(), (n) => n === 3, WAIT_MS, "3 plots again");
    await screenshot(page, "developer-1920x1080.png");

    // logger: only "Stop" selected → stops show, control transfers do not
    await page.locator("#cat-none").click();
    await page.locator('[data-testid="cat-stop"]').check();
    await takeHelm(pilot.page);
    await pilot.page.evaluate(() => window.dispatchEvent(new Event("blur")));
    const list = page.locator('[data-testid="log-list"]');
    await list.locator('li[data-category="stop"]', { hasText: "stopped: window lost focus" }).waitFor();
    assert.equal(await list.locator('li[data-category="transfer"]').count(), 0, "a deselected category is shown");
    // select "Transfer of control" and "Safety" (the server's log topic): they show up
    await page.locator('[data-testid="cat-transfer"]').check();
    await page.locator('[data-testid="cat-safety"]').check();
    await list.locator('li[data-category="transfer"]', { hasText: "e2e-dev-pilot pilots" }).first().waitFor();
    await list.locator('li[data-category="safety"]', { hasText: "window lost focus" }).first().waitFor();
    assert.match((await list.locator("li time").first().textContent()) ?? "", /^\d\d:\d\d:\d\d\.\d{3}$/);
    // filter text and pause
    await page.locator("#log-filter").fill("pilots");
    await until(() => list.locator("li").count(), (n) => n >= 1, WAIT_MS, "filtered entries");
    assert.equal(await list.locator('li[data-category="stop"]').count(), 0, "the filter let a stop through");
    await page.locator("#log-filter").fill("");
    await page.locator("#log-pause").click();
    const frozen = await list.locator("li").count();
    await pilot.page.locator("#release-control").click();
    await page.locator("#log-pause", { hasText: /Resume \([1-9]\d* new\)/ }).waitFor();
    assert.equal(await list.locator("li").count(), frozen, "entries arrived while paused");
    await page.locator("#log-pause").click();
    await until(() => list.locator("li").count(), (n) => n > frozen, WAIT_MS, "entries after resume");
    const [logFile] = await Promise.all([page.waitForEvent("download"), page.locator("#log-download").click()]);
    assert.match(readFileSync(await logFile.path(), "utf8"), /\tstop\twarning\tstopped: window lost focus/);
    await page.locator("#log-clear").click();
    assert.equal(await list.locator("li").count(), 0);

    await page.locator("#remove-plots").click();
    assert.equal(await plots(page).count(), 0);

    // tablet layout: readable, nothing wider than the screen
    await page.setViewportSize(TABLET);
    for (let i = 0; i < 3; i++) await page.locator("#add-plot").click();
    await page.locator("#cat-all").click();
    await page.waitForTimeout(300);
    const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
    assert.ok(overflow <= 0, `developer page is ${overflow}px wider than 1024px`);
    await screenshot(page, "developer-1024x768.png");
    await page.locator("#reset-plots").click();
    await until(() => plotsStatus(page), (s) => s === "default", WAIT_MS, "default plots after the test");
    assertNoPageProblems();
  } finally {
    await dev.context.close();
    await pilot.context.close();
  }
});

test("developer page: the server's recordings: list, CSV download, shown in the plots, back to live", { timeout: TEST_MS }, async () => {
  const name = process.env.E2E_RECORDING;
  assert.ok(name, "E2E_RECORDING names the recording the server holds (set by external_test.exs)");
  const dev = await open(browser, { ...TABLET, name: "e2e-dev-rec", path: "/dev.html" });
  try {
    const { page } = dev;
    await until(() => samples(page), (n) => n > 2, WAIT_MS, "live samples");
    await page.locator("#recordings summary").click();
    const item = page.locator(`[data-testid="recording-list"] li[data-name="${name}"]`);
    await item.waitFor();

    // the CSV export, as a download
    const [download] = await Promise.all([page.waitForEvent("download"), item.locator("a", { hasText: "CSV" }).click()]);
    const csv = readFileSync(await download.path(), "utf8").split("\n").filter((l) => l !== "");
    assert.equal(csv[0], "time,measurement.depth,measurement.heading,sent_at,t");
    assert.equal(csv.length, 301);

    // shown in the plots instead of live telemetry
    await item.locator("button.replay").click();
    await page.locator('[data-testid="replay"][data-state="shown"]').waitFor();
    assert.match((await page.locator("#replay").textContent()) ?? "", /300 samples, 1 event\./);
    assert.equal(await samples(page), 300);
    await page.waitForTimeout(500);
    assert.equal(await samples(page), 300, "live samples were mixed into the recording");
    await noPlots(page);
    await page.locator("#add-plot").click();
    await plots(page).first().locator("canvas").waitFor();
    assert.equal(await plots(page).first().getAttribute("data-series"), "measurement.depth");
    await page.locator('[data-testid="log-list"] li[data-category="recording"]', { hasText: `showing recording ${name}` }).waitFor();
    // and its events in the logger, marked as recorded
    await page.locator('[data-testid="log-list"] li[data-category="stop"]', { hasText: "[recorded] stopped: deadman" }).waitFor();
    await screenshot(page, "developer-recording-1024x768.png", { fullPage: false });

    // back to live: the buffer starts afresh and fills again
    await page.locator("#back-to-live").click();
    await until(() => samples(page), (n) => n > 0 && n < 300, WAIT_MS, "live samples again");
    assert.equal(await page.locator("#replay").count(), 0);

    // delete it (after the confirmation dialog): gone from the server's list
    page.once("dialog", (dialog) => dialog.accept());
    await item.locator("button.delete-recording").click();
    await item.waitFor({ state: "detached" });
    await page.locator('[data-testid="log-list"] li[data-category="recording"]', { hasText: `deleted recording ${name}` }).waitFor();
    await page.locator("#reset-plots").click();
    await until(() => plotsStatus(page), (s) => s === "default", WAIT_MS, "default plots after the test");
    assertNoPageProblems();
  } finally {
    await dev.context.close();
  }
});

test("developer page: autopilot tuning — only the pilot previews a step and applies gains", { timeout: TEST_MS }, async () => {
  const user = "e2e-tuner";
  const pilot = await open(browser, { ...TABLET, name: user });
  const dev = await open(browser, { ...DESKTOP, name: user, path: `/dev.html?name=${user}` });
  try {
    const { page } = dev;
    await page.locator("#tuning summary").click();
    await page.locator('[data-testid="gain-depth-kp"]').waitFor();
    assert.equal(await page.locator('[data-testid="gain-depth-kp"]').inputValue(), "3");

    // not piloting: the server refuses, and the page says why
    await page.locator("#tuning-preview").click();
    await page.locator('[data-testid="tuning-message"][data-state="error"]', { hasText: "tuning is for the pilot or the main station" }).waitFor();

    // the same user pilots on the operator page: the preview runs on the simulator model
    await waitTelemetry(pilot.page);
    await takeHelm(pilot.page);
    await page.locator('[data-testid="gain-depth-kp"]').fill("6");
    await page.locator("#tuning-preview").click();
    await page.locator('[data-testid="step-preview"] polyline').first().waitFor();
    assert.match((await page.locator('[data-testid="step-figures"]').textContent()) ?? "", /depth step on the simulator model: overshoot [\d.]+ cm, within ±5 cm after [\d.]+ s/);

    // a bad gain is caught before the server
    await page.locator('[data-testid="gain-heading-kd"]').fill("99");
    await page.locator("#tuning-apply").click();
    await page.locator('[data-testid="tuning-message"][data-state="error"]', { hasText: "heading.kd must be a number in [0, 20]" }).waitFor();
    await page.locator('[data-testid="gain-heading-kd"]').fill("2");

    await page.locator("#tuning-apply").click();
    await page.locator('[data-testid="tuning-message"][data-state="ok"]', { hasText: "applied to the vehicle and stored" }).waitFor();
    assert.equal(await page.locator('[data-testid="gain-depth-kp"]').inputValue(), "6");
    await screenshot(page, "developer-tuning-1920x1080.png", { fullPage: false });

    // back to the defaults (the vehicle's stored tuning is shared by the later tests)
    await page.locator("#tuning-defaults").click();
    await page.locator("#tuning-apply").click();
    await page.locator('[data-testid="tuning-message"][data-state="ok"]', { hasText: "applied" }).waitFor();
    assert.equal(await page.locator('[data-testid="gain-depth-kp"]').inputValue(), "3");
    assertNoPageProblems();
  } finally {
    await dev.context.close();
    await pilot.context.close();
  }
});
