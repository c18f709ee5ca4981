// The fleet page of a running `odonav-ground serve` in a real browser: Debian's chromium, headless,
// driven by puppeteer-core. Prints one JSON line per event on stdout for the test to read:
//   {"event":"ready", "rows"}       the table once every vehicle shows K converged and all components OK
//   {"event":"refused", "log"}      set K without the token: refused, shown in the command log
//   {"event":"set_k", "log", "dr"}  set K with the token: acknowledged, then DR's K column
//   {"event":"kill-now"}            the test SIGKILLs VEHICLE's identification when it reads this
//   {"event":"stale", "after_s", "rows"}  the page marks it STALE
//   {"event":"done", "screenshot"}
// Usage: node page_check.js PORT TOKEN SCREENSHOT VEHICLE[,VEHICLE...] SET_K_VALUE
"use strict";
const fs = require("fs");
const os = require("os");
const path = require("path");
const puppeteer = require("puppeteer-core");

const [port, token, screenshot, vehicleList, setK] = process.argv.slice(2);
const vehicles = vehicleList.split(",");
const target = vehicles[0];
const out = (o) => process.stdout.write(JSON.stringify(o) + "\n");
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function rows(page) {
  return page.evaluate(() => {
    const r = {};
    for (const tr of document.querySelectorAll("#fleet tbody tr.vehicle")) {
      const cell = (c) => tr.querySelector("td." + c.split(" ")[0]).textContent;
      const comps = {};
      for (const s of tr.querySelectorAll("span.comp")) comps[s.dataset.component] = s.dataset.level;
      r[tr.dataset.vehicle] = { stale: tr.dataset.stale === "true", k: cell("k"), sigma: cell("sigma"),
                                source: cell("source"), estimator: cell("estimator"), mis: cell("mis"), dr_k: cell("dr-k"), dr_error: cell("dr-error"),
                                gnss: cell("gnss"), gaps: cell("gaps"), components: comps };
    }
    return r;
  });
}
async function until(what, ms, fn) {
  const end = Date.now() + ms;
  let last;
  while (Date.now() < end) {
    last = await fn();
    if (last.ok) return last;
    await sleep(250);
  }
  throw new Error(`${what}: not within ${ms / 1000} s; last: ${JSON.stringify(last)}`);
}
async function lastLog(page) {
  return page.evaluate(() => {
    const d = document.querySelector("#command-log div");
    return d ? { outcome: d.dataset.outcome, text: d.textContent } : null;
  });
}

async function main() {
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), "odonav-chromium-"));
  const browser = await puppeteer.launch({
    executablePath: "/usr/bin/chromium",
    headless: true,
    userDataDir: profile,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--disable-dev-shm-usage"],
  });
  try {
    const page = await browser.newPage();
    await page.setViewport({ width: 1400, height: 900 });
    const failed = [];
    page.on("requestfailed", (r) => failed.push(r.url()));
    page.on("request", (r) => { if (!r.url().startsWith(`http://127.0.0.1:${port}/`)) failed.push("outside: " + r.url()); });
    page.on("dialog", (d) => d.accept());  // the set-K confirmation
    await page.goto(`http://127.0.0.1:${port}/`, { waitUntil: "load" });

    const ready = await until("every vehicle with K and all components OK", 120000, async () => {
      const r = await rows(page);
      // K converged (the estimator no longer "converging", a sigma shown) and DR with an error.
      const ok = vehicles.every((v) => r[v] && r[v].k !== "–" && r[v].sigma !== "–" &&
                                       !r[v].estimator.includes("converging") && r[v].dr_error !== "–" &&
                                       Object.keys(r[v].components).length >= 4 &&
                                       Object.values(r[v].components).every((l) => l === "OK"));
      return { ok, rows: r };
    });
    out({ event: "ready", rows: ready.rows, outside_or_failed_requests: failed });

    // Set K on the target's dead reckoning: first without the token (refused), then with it.
    await page.click(`tr.vehicle[data-vehicle="${target}"]`);
    await page.select("#component", "odonav-dead-reckoning");
    await page.$eval("#k-value", (e, v) => { e.value = v; }, setK);
    await page.click("#cmd-set-k");
    const refused = await until("refusal without the token", 20000, async () => {
      const l = await lastLog(page);
      return { ok: !!l, log: l };
    });
    out({ event: "refused", log: refused.log });
    await page.type("#token", token);
    await page.click("#cmd-set-k");
    const acked = await until("acknowledgement with the token", 20000, async () => {
      const l = await lastLog(page);
      return { ok: !!l && l.outcome !== "REFUSED", log: l };
    });
    const dr = await until("DR navigating with the commanded K", 20000, async () => {
      const r = await rows(page);
      return { ok: r[target].dr_k.includes("commanded"), dr_k: r[target].dr_k };
    });
    out({ event: "set_k", log: acked.log, dr_k: dr.dr_k });

    out({ event: "kill-now" });
    const killedAt = Date.now();
    const stale = await until("the killed identification STALE", 30000, async () => {
      const r = await rows(page);
      return { ok: r[target].components["odonav-identification"] === "STALE", rows: r };
    });
    out({ event: "stale", after_s: (Date.now() - killedAt) / 1000, rows: stale.rows });
    await sleep(1200);  // one more refresh: the screenshot shows the final state
    await page.screenshot({ path: screenshot, fullPage: true });
    out({ event: "done", screenshot, outside_or_failed_requests: failed });
  } finally {
    await browser.close();
    fs.rmSync(profile, { recursive: true, force: true });
  }
}
main().catch((e) => { out({ event: "error", error: String(e && e.stack || e) }); process.exit(1); });
