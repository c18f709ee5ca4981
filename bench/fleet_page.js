// The browser of the fleet-scale benchmark (bench/fleet_bench.sh): Debian's chromium, headless,
// with the fleet page of `odonav-ground serve` open (it polls /api/fleet every second) for SECONDS.
// Usage: node fleet_page.js PORT SECONDS. NODE_PATH: the npm folder (puppeteer-core).
"use strict";
const fs = require("fs"), os = require("os"), path = require("path");
const puppeteer = require("puppeteer-core");
const [port, seconds] = process.argv.slice(2).map(Number);
(async () => {
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), "odonav-bench-chromium-"));
  const browser = await puppeteer.launch({
    executablePath: "/usr/bin/chromium", headless: true, userDataDir: profile,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage"],
  });
  const page = await browser.newPage();
  await page.goto(`http://127.0.0.1:${port}/`, { waitUntil: "load" });
  await new Promise((r) => setTimeout(r, seconds * 1000));
  const rows = await page.evaluate(() => document.querySelectorAll("#fleet tbody tr.vehicle").length);
  process.stdout.write(JSON.stringify({ rows }) + "\n");
  await browser.close();
  fs.rmSync(profile, { recursive: true, force: true });
})().catch((e) => { process.stdout.write(JSON.stringify({ error: String(e) }) + "\n"); process.exit(1); });
