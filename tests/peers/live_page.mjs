// Drives treemocap's live page in Debian's headless Chromium for the Rust
// integration tests (tests/it/live_view.rs), through playwright-core.
//
//   node tests/peers/live_page.mjs URL
//
// Reads one JSON command per line on stdin and answers one JSON line on
// stdout, so the Rust test decides what to check and when:
//   {"cmd":"state"}                         -> {"state": window.treemocap as JSON}
//   {"cmd":"wait","expr":JS,"timeout_ms":N} -> {"ok":bool,"ms":elapsed}
//   {"cmd":"eval","expr":JS}                -> {"value":...}
//   {"cmd":"click","selector":CSS}          -> {"ok":true}
//   {"cmd":"screenshot","path":FILE}        -> {"ok":true}
//   {"cmd":"errors"}                        -> {"errors":[console errors and page errors]}
//   {"cmd":"quit"}
// The first line it prints is {"ready":true} once the page has loaded.
import readline from 'node:readline';
import { chromium } from 'playwright-core';

const url = process.argv[2];
const userDir = process.argv[3];
// The flags that work on this project's machines (no GPU, no network but
// loopback): software WebGL through SwiftShader, nothing phoning home.
const browser = await chromium.launchPersistentContext(userDir, {
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  headless: true,
  viewport: { width: 1280, height: 800 },
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const page = browser.pages()[0] ?? await browser.newPage();
const errors = [];
page.on('console', (m) => { if (m.type() === 'error') errors.push(`console: ${m.text()}`); });
page.on('pageerror', (e) => errors.push(`page: ${e.message}`));
const say = (o) => process.stdout.write(JSON.stringify(o) + '\n');

await page.goto(url);
await page.waitForFunction(() => window.treemocap?.ready === true, null, { timeout: 30000 });
say({ ready: true });

const rl = readline.createInterface({ input: process.stdin });
for await (const line of rl) {
  if (!line.trim()) continue;
  const c = JSON.parse(line);
  try {
    if (c.cmd === 'quit') break;
    if (c.cmd === 'state') say({ state: await page.evaluate(() => JSON.parse(JSON.stringify(window.treemocap))) });
    else if (c.cmd === 'errors') say({ errors });
    else if (c.cmd === 'eval') say({ value: await page.evaluate(c.expr) });
    else if (c.cmd === 'click') { await page.click(c.selector); say({ ok: true }); }
    else if (c.cmd === 'screenshot') { await page.screenshot({ path: c.path }); say({ ok: true }); }
    else if (c.cmd === 'wait') {
      const t0 = Date.now();
      try {
        await page.waitForFunction(c.expr, null, { timeout: c.timeout_ms ?? 10000, polling: 'raf' });
        say({ ok: true, ms: Date.now() - t0 });
      } catch {
        say({ ok: false, ms: Date.now() - t0 });
      }
    } else say({ error: `unknown command ${c.cmd}` });
  } catch (e) {
    say({ error: String(e) });
  }
}
await browser.close();
