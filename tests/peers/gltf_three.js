// Plays a glb's first animation the way a web viewer does: three.js's
// GLTFLoader and AnimationMixer, in headless Chromium (Debian's package, driven
// by playwright-core). Prints, as one JSON line, the world positions of the
// named nodes at the given times: {"<time>": {"<name>": [x, y, z]}}.
//
// usage: node gltf_three.js FILE.glb '[t0, t1, ...]' '["tip_00", ...]'
// Chromium: $CHROMIUM, else /usr/bin/chromium. Exit 3 when a peer is missing.
const http = require('http');
const fs = require('fs');
const path = require('path');

let chromium;
let threeDir;
try {
  ({ chromium } = require('playwright-core'));
  threeDir = path.dirname(path.dirname(require.resolve('three')));
} catch (e) {
  console.error('three or playwright-core is not installed: run `npm install --prefix tests/peers`');
  process.exit(3);
}
const executablePath = process.env.CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(executablePath)) {
  console.error(`no Chromium at ${executablePath}: apt-get install chromium (or set CHROMIUM)`);
  process.exit(3);
}
const [glbPath, timesArg, namesArg] = process.argv.slice(2);
const times = JSON.parse(timesArg);
const names = JSON.parse(namesArg);

// The page: an import map for three's ES modules, and one function that
// loads the model, samples the animation and reads world positions.
const page = `<!doctype html>
<script type="importmap">{"imports":{"three":"/three/build/three.module.js","three/addons/":"/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
window.sample = async (times, names) => {
  const gltf = await new GLTFLoader().loadAsync('/model.glb');
  if (gltf.animations.length === 0) throw new Error('the file has no animation');
  const mixer = new THREE.AnimationMixer(gltf.scene);
  mixer.clipAction(gltf.animations[0]).play();
  const out = {};
  for (const t of times) {
    mixer.setTime(t);
    gltf.scene.updateMatrixWorld(true);
    const row = {};
    for (const name of names) {
      const node = gltf.scene.getObjectByName(name);
      if (!node) throw new Error('no node named ' + name);
      const v = node.getWorldPosition(new THREE.Vector3());
      row[name] = [v.x, v.y, v.z];
    }
    out[String(t)] = row;
  }
  return out;
};
window.ready = true;
</script>`;

// Serves the page, the model and three's files, on loopback only.
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  if (url === '/') {
    res.writeHead(200, { 'content-type': 'text/html' });
    return res.end(page);
  }
  let file = null;
  let type = 'application/octet-stream';
  if (url === '/model.glb') {
    file = glbPath;
  } else if (url.startsWith('/three/')) {
    const candidate = path.join(threeDir, path.normalize(url.slice('/three/'.length)));
    if (candidate.startsWith(threeDir + path.sep)) file = candidate;
    type = 'text/javascript';
  }
  if (!file || !fs.existsSync(file)) {
    res.writeHead(404);
    return res.end();
  }
  res.writeHead(200, { 'content-type': type });
  fs.createReadStream(file).pipe(res);
});

server.listen(0, '127.0.0.1', async () => {
  let browser;
  let code = 0;
  try {
    browser = await chromium.launch({ executablePath, args: ['--no-sandbox'] });
    const tab = await browser.newPage();
    const errors = [];
    tab.on('pageerror', (e) => errors.push(String(e)));
    await tab.goto(`http://127.0.0.1:${server.address().port}/`);
    await tab.waitForFunction(() => window.ready === true, null, { timeout: 30000 }).catch((e) => {
      throw new Error(`page did not load: ${errors.join('; ') || e}`);
    });
    const result = await tab.evaluate(([t, n]) => window.sample(t, n), [times, names]);
    console.log(JSON.stringify(result));
  } catch (e) {
    console.error(String(e));
    code = 2;
  } finally {
    if (browser) await browser.close();
    server.close();
    process.exitCode = code;
  }
});
