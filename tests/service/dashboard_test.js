// The dashboard in headless Chromium (puppeteer-core, dashboard/package.json):
// the page asks for the token once and keeps it in an HttpOnly, SameSite
// Strict cookie; a spec submitted through its form appears in the jobs
// table; the job's convergence plot grows as evaluations come in, and its
// best parameters show; a bad spec shows the server's message naming the
// field; an optimiser comparison submitted through the form shows its kind
// in the table and, once done, its report embedded in the page. Exit 0 when
// all holds. Run by ctest (tests/CMakeLists.txt) with
// CALIB_EXE, CALIB_SOURCE_DIR and CALIB_CHROMIUM set; CALIB_SCREENSHOT_DIR,
// when set, receives dashboard.png and dashboard_comparison.png.
"use strict";
const { spawn } = require("child_process");
const fs = require("fs");
const os = require("os");
const path = require("path");

const source = process.env.CALIB_SOURCE_DIR;
const puppeteer = require(path.join(source, "dashboard", "node_modules", "puppeteer-core"));

function fail(message) {
  console.error("FAILED: " + message);
  process.exitCode = 1;
  throw new Error(message);
}

function check(condition, message) {
  if (!condition) fail(message);
}

async function waitFor(what, predicate, timeoutMs) {
  const deadline = Date.now() + timeoutMs;
  while (Date.now() < deadline) {
    const value = await predicate();
    if (value) return value;
    await new Promise((r) => setTimeout(r, 100));
  }
  fail(`${what}: not after ${timeoutMs / 1000} s`);
}

// The base model on a coarse mesh: what every spec here searches.
const coarseModel = `model: {substeps: 4, mesh: {edge_length_px: 40}}
parameters:
  - {name: k_D, lower: 10, upper: 5000, scale: log}
  - {name: k_d, lower: 0.01, upper: 50, scale: log}
  - {name: k_A, lower: 1, upper: 5000, scale: log}
  - {name: k_phi, lower: 0.1, upper: 1000, scale: log}
  - {name: mass, fixed: 0.2}
  - {name: tau, lower: 0, upper: 0.5}
`;

// The job's evaluations: enough for a few seconds of search, so that its
// plot is seen growing between the page's refreshes (every second) on a
// fast machine too.
const kBudget = 96;

const jobYaml = (name, budget) => `
name: ${name}
train: [push_centre]
${coarseModel}optimizer: {name: cmaes, settings: {population: 4}}
budget: {evaluations: ${budget}}
seed: 3
`;

// The smallest comparison: two optimisers, one seed, 3 evaluations each.
const comparisonYaml = (name) => `
name: ${name}
train: [push_centre]
${coarseModel}budget: {evaluations: 3}
optimizers: [{name: random}, {name: cmaes, settings: {population: 3}}]
seeds: 1
`;

// Submits `yaml` as `kind` through the form and waits for the page to say
// it is queued; a refusal fails with the page's message.
async function submitThroughForm(page, kind, name, yaml) {
  await page.select("#kind", kind);
  await page.$eval("#spec", (e, v) => { e.value = v; }, yaml);
  await page.$eval("#submit-result", (e) => { e.textContent = ""; });
  await page.click("#submit-form button");
  const said = async () => page.$eval("#submit-result", (e) => e.textContent);
  const deadline = Date.now() + 30000;
  while (!(await said())) {
    if (Date.now() > deadline) fail(`submitting ${kind} ${name}: the page said nothing after 30 s`);
    await new Promise((r) => setTimeout(r, 100));
  }
  const text = await said();
  check(text.startsWith(`queued: ${kind} ${name}`), `submitting ${kind} ${name}: the page said '${text}'`);
  await page.waitForSelector(`tr.job[data-name="${name}"]`, { timeout: 10000 });
}

async function main() {
  const state = fs.mkdtempSync(path.join(os.tmpdir(), "calib_dashboard_"));
  const server = spawn(process.env.CALIB_EXE, [
    "serve", "--port", "0", "--port-file", path.join(state, "port"), "--state-dir", state,
    "--data-root", path.join(source, "examples"), "--jobs", "1", "--threads-per-job", "1", "--no-report",
  ], { stdio: ["ignore", "ignore", "inherit"] });
  let browser = null;
  let passed = false;
  try {
    await waitFor("the server's port file", () => fs.existsSync(path.join(state, "port")), 30000);
    const port = fs.readFileSync(path.join(state, "port"), "utf8").trim();
    const token = fs.readFileSync(path.join(state, "token"), "utf8").trim();
    const url = `http://127.0.0.1:${port}/`;

    browser = await puppeteer.launch({
      executablePath: process.env.CALIB_CHROMIUM,
      args: ["--no-sandbox", "--disable-gpu"],
      headless: true,
    });
    const page = await browser.newPage();
    await page.setViewport({ width: 1000, height: 1100 });
    await page.goto(url);
    await page.waitForSelector("#login", { visible: true });

    await page.type("#token", "not-the-token");
    await page.click("#login-form button");
    await waitFor("a wrong token named", async () =>
      (await page.$eval("#login-error", (e) => e.textContent)).includes("wrong token"), 10000);
    await page.$eval("#token", (e) => { e.value = ""; });
    await page.type("#token", token);
    await page.click("#login-form button");
    await page.waitForSelector("#main", { visible: true });
    const cookies = await page.cookies();
    const cookie = cookies.find((c) => c.name === "calib_token");
    check(cookie !== undefined, "no calib_token cookie after signing in");
    check(cookie.httpOnly, "the cookie is not HttpOnly");
    check(cookie.sameSite === "Strict", `the cookie is SameSite=${cookie.sameSite}, not Strict`);
    check(!(await page.evaluate(() => document.cookie)).includes("calib_token"),
          "the page's script can read the token");

    // A bad spec: the server's message, naming the field.
    await page.$eval("#spec", (e, v) => { e.value = v; }, jobYaml("bad", 0));
    await page.click("#submit-form button");
    await waitFor("the bad spec's message", async () =>
      (await page.$eval("#submit-result", (e) => e.textContent)).includes("budget.evaluations = '0'"), 10000);

    await submitThroughForm(page, "job", "from_dashboard", jobYaml("from_dashboard", kBudget));
    await page.click('tr.job[data-name="from_dashboard"]');
    const points = async () => Number(await page.$eval("#chart", (e) => e.dataset.points || 0));
    const first = await waitFor("the plot's first points", async () => {
      const n = await points();
      return n > 0 ? n : 0;
    }, 60000);
    await waitFor("the plot growing", async () => (await points()) > first, 60000);
    await waitFor("the best parameters", async () =>
      (await page.$$("#parameters tr")).length === 6, 10000);
    await waitFor("the job finished in the table", async () =>
      (await page.$eval('tr.job[data-name="from_dashboard"]', (e) => e.textContent)).includes(`${kBudget}/${kBudget}`), 90000);
    await waitFor("the job's detail at its end", async () =>
      (await page.$eval("#detail-status", (e) => e.textContent)).includes(`${kBudget}/${kBudget}`), 30000);
    if (process.env.CALIB_SCREENSHOT_DIR) {
      await page.screenshot({ path: path.join(process.env.CALIB_SCREENSHOT_DIR, "dashboard.png"), fullPage: true });
    }
    const grown = await points();

    // A comparison: its kind in the table, its report embedded once done.
    await submitThroughForm(page, "comparison", "compared_in_dashboard", comparisonYaml("compared_in_dashboard"));
    const row = 'tr.job[data-name="compared_in_dashboard"]';
    check((await page.$eval(`${row} td:nth-child(2)`, (e) => e.textContent)) === "comparison",
          "the table does not show the comparison's kind");
    await page.click(row);
    await waitFor("the comparison's report embedded", async () => {
      const frame = page.frames().find((f) => f.url().endsWith("/compared_in_dashboard/artefacts/report.html"));
      return frame !== undefined && (await frame.content()).includes("compared_in_dashboard");
    }, 90000);
    check((await page.$eval("#report-link", (e) => e.textContent)).includes("comparison report: report.html"),
          "no link to the comparison's report");
    if (process.env.CALIB_SCREENSHOT_DIR) {
      await page.screenshot({ path: path.join(process.env.CALIB_SCREENSHOT_DIR, "dashboard_comparison.png"), fullPage: true });
    }
    console.log(`dashboard: signed in, a bad spec named, a job submitted, its plot grew from ${first} to ${grown} points; a comparison's report embedded`);
    passed = !process.exitCode;
  } finally {
    if (browser) await browser.close();
    const exited = server.exitCode !== null || server.signalCode !== null
      ? Promise.resolve()
      : new Promise((resolve) => server.once("exit", resolve));
    server.kill("SIGTERM");
    await exited;
    // The server's state folder goes with a passing run; a failing run's
    // stays for a look.
    if (passed) fs.rmSync(state, { recursive: true, force: true });
    else console.error(`state kept: ${state}`);
  }
}

main().catch((e) => {
  if (!process.exitCode) console.error("FAILED: " + (e && e.stack ? e.stack : e));
  process.exitCode = 1;
});
