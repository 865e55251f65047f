// The tiles in a real browser: Debian's Chromium, headless with software WebGL, driven by
// playwright-core, loads the viewer page of scripts/view (three.js and 3DTilesRendererJS) from a
// server on 127.0.0.1 and checks, from its pixels and the renderer's own counters:
//   - every tileset loads without an error (load errors, page errors, console errors);
//   - level of detail: from afar the renderer loads a few coarse tiles; close up it shows leaf tiles;
//     where dragon_vrip spans 512 pixels, at the renderer's default error target, it loads at most
//     10% of the triangles and its silhouette differs from the full-resolution render's in at most
//     1% of the silhouette's pixels;
//   - cracks: at 5 distances, where levels mix, no pixel that the full-resolution render covers shows
//     background in the tiled render farther than 2 pixels from the full-resolution outline (at an
//     error target of 2 pixels); at the default target (16 pixels), where an outline may move by
//     its level's error, no background deeper than 16 pixels inside it (the errors are bounds);
//   - every glb passes gltf-validator, and check_tileset.py passes (geometric errors, boxes, URIs).
// The full-resolution render is the same tileset with error target 0 (every leaf). Prints one JSON
// object of what it measured; exits 1 naming every failure.
// Meshes: dragon_vrip, fg_hawaii and a `facetree gen assembly` mesh.
//   NODE_PATH=NODE_MODULES node browser_test.cjs FACETREE SHARED_DATA OUT_DIR
const { chromium } = require('playwright-core');
const validator = require('gltf-validator');
const { spawn, execFileSync } = require('child_process');
const fs = require('fs');
const path = require('path');

const [cli, data, out] = process.argv.slice(2);
const here = __dirname, root = path.resolve(here, '..', '..');
const nodeModules = process.env.NODE_PATH;
const failures = [];
const check = (ok, what) => { if (!ok) failures.push(what); return ok; };
const W = 800, H = 600;

function run(...args) { return execFileSync(args[0], args.slice(1), { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] }); }

async function validateGlbs(dir) {
  let files = 0, errors = 0;
  const walk = (d) => fs.readdirSync(d, { withFileTypes: true }).flatMap((e) =>
    e.isDirectory() ? walk(path.join(d, e.name)) : e.name.endsWith('.glb') ? [path.join(d, e.name)] : []);
  for (const file of walk(dir)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), { uri: file });
    files++;
    if (report.issues.numErrors) {
      errors++;
      failures.push(`${file}: gltf-validator: ${report.issues.messages.filter((m) => m.severity === 0).map((m) => m.code).join(', ')}`);
    }
  }
  return { files, errors };
}

// The first vertex of a glb written without Draco, in the tileset's z-up frame.
function firstVertex(file) {
  const bytes = fs.readFileSync(file);
  const jsonLength = bytes.readUInt32LE(12);
  const gltf = JSON.parse(bytes.subarray(20, 20 + jsonLength).toString());
  const bin = 20 + jsonLength + 8;
  const t = gltf.nodes[0].translation ?? [0, 0, 0];
  const [x, y, z] = [0, 1, 2].map((k) => t[k] + bytes.readFloatLE(bin + 4 * k));
  return [x, -z, y];
}

function serve(dir) {
  return new Promise((resolve, reject) => {
    const server = spawn('/usr/bin/python3', [path.join(root, 'scripts', 'viewer', 'serve.py'), dir, nodeModules]);
    server.stdout.once('data', (line) => resolve({ server, url: String(line).trim() }));
    server.stderr.on('data', (e) => process.stderr.write(e));
    server.once('exit', (code) => reject(new Error(`serve.py exited ${code}`)));
  });
}

async function view(page, url, query) {
  await page.goto(`${url}?${query}`);
  await page.waitForFunction(() => window.facetreeViewer);
  const stats = await page.evaluate(() => window.facetreeViewer.settle());
  const mask = await page.evaluate(() => window.facetreeViewer.maskBase64());
  const bits = Buffer.from(mask.bits, 'base64');
  let covered = 0, minX = W, maxX = -1, minY = H, maxY = -1;
  for (let y = 0; y < H; y++)
    for (let x = 0; x < W; x++)
      if (bits[y * W + x]) covered++, minX = Math.min(minX, x), maxX = Math.max(maxX, x), minY = Math.min(minY, y), maxY = Math.max(maxY, y);
  return { stats, bits, covered, span: covered ? Math.max(maxX - minX + 1, maxY - minY + 1) : 0 };
}

// Pixels the full render covers that the tiled one leaves as background, more than 2 pixels from
// any background pixel of the full render (its outline), and how deep the deepest lies; and pixels
// that differ at all.
function compare(full, tiled) {
  let holes = 0, differ = 0, deepest = 0;
  for (let y = 0; y < H; y++)
    for (let x = 0; x < W; x++) {
      const i = y * W + x;
      if (full.bits[i] !== tiled.bits[i]) differ++;
      if (!full.bits[i] || tiled.bits[i]) continue;
      const d = depth(full, x, y);
      if (d > 2) holes++;
      deepest = Math.max(deepest, d);
    }
  return { holes, differ, deepest };
}

// How far a covered pixel of the full render lies from its outline: the half-width of the
// smallest square around it that holds a background pixel (at most 64).
function depth(full, x, y) {
  for (let r = 1; r <= 64; r++)
    for (let d = -r; d <= r; d++)
      for (const [xx, yy] of [[x + d, y - r], [x + d, y + r], [x - r, y + d], [x + r, y + d]])
        if (xx < 0 || yy < 0 || xx >= W || yy >= H || !full.bits[yy * W + xx]) return r;
  return 65;
}

async function testMesh(browser, name, mesh, triangles) {
  const dir = path.join(out, name);
  fs.mkdirSync(dir, { recursive: true });
  const fch = path.join(dir, `${name}.fch`), tiles = path.join(dir, 'tiles');
  run(cli, 'build', mesh, '-o', fch);
  const report = JSON.parse(run(cli, 'tiles', fch, '-o', tiles, '--tile-faces', '8192', '--json'));
  const result = { tiles: report.tiles, leaf_tiles: report.leaf_tiles, levels: report.levels,
                   bytes_over_leaves: report.bytes / report.leaf_bytes };
  try {
    result.check = JSON.parse(run('/usr/bin/python3', path.join(here, 'check_tileset.py'), tiles, '--triangles', String(triangles)));
  } catch (e) {
    failures.push(`${name}: check_tileset.py: ${e.stderr}`);
  }
  result.gltf_validator = await validateGlbs(tiles);
  const tileset = JSON.parse(fs.readFileSync(path.join(tiles, 'tileset.json')));
  const leaves = [];
  const walk = (t) => (t.children?.length ? t.children.forEach(walk) : leaves.push(t));
  walk(tileset.root);
  // A point on the surface: the first vertex of a leaf in the middle of the face order.
  const target = firstVertex(path.join(tiles, leaves[Math.floor(leaves.length / 2)].content.uri)).join(',');
  // Close views by the root's error: where it covers 200, 40 and 8 pixels, the renderer refines
  // near the camera and keeps coarser levels farther off.
  const rootError = tileset.root.geometricError;
  const rangeFor = (pixels) => (rootError * H) / (2 * Math.tan(Math.PI / 8) * pixels);
  const { server, url } = await serve(tiles);
  const page = await browser.newPage({ viewport: { width: W, height: H } });
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(e.message));
  page.on('console', (m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
  try {
    // From afar: the root and a few coarse tiles, nothing at full resolution.
    const far = await view(page, url, 'mask&distance=40');
    result.far = { loaded_tiles: far.stats.loadedTiles, visible_leaf_tiles: far.stats.visibleLeafTiles };
    check(far.stats.loadedTiles <= 3 && far.stats.visibleLeafTiles === 0, `${name}: from afar ${far.stats.loadedTiles} tiles loaded, ${far.stats.visibleLeafTiles} leaves shown`);
    // Close up: leaf tiles.
    const close = await view(page, url, `mask&target=${target}&range=${rangeFor(200)}`);
    result.close = { visible_tiles: close.stats.visibleTiles, visible_leaf_tiles: close.stats.visibleLeafTiles };
    check(close.stats.visibleLeafTiles > 0, `${name}: close up no leaf tile shown`);
    // Cracks at 5 distances, near views looking at a leaf so that levels mix. Checked at an error
    // target of 2 pixels, where the levels' own error stays within the 2-pixel outline allowance
    // and what shows through can only be a crack; at the default target (16 pixels) the coarser
    // levels' outline may move by more, which the figures report.
    result.cracks = [];
    for (const query of [`target=${target}&range=${rangeFor(200)}`, `target=${target}&range=${rangeFor(40)}`,
                         `target=${target}&range=${rangeFor(8)}&azimuth=120`,
                         'distance=1.5&azimuth=200&elevation=40', 'distance=3']) {
      const full = await view(page, url, `mask&errorTarget=0&${query}`);
      const tiled = await view(page, url, `mask&errorTarget=2&${query}`);
      const byDefault = await view(page, url, `mask&${query}`);
      const { holes } = compare(full, tiled), atDefault = compare(full, byDefault);
      result.cracks.push({ view: query, holes, holes_default_target: atDefault.holes, deepest_default_target: atDefault.deepest,
                           covered: full.covered,
                           visible_tiles: tiled.stats.visibleTiles, visible_leaf_tiles: tiled.stats.visibleLeafTiles });
      check(holes === 0, `${name}: ${holes} background pixels inside the surface at ${query}`);
      // At the default target each level may move the outline by up to its screen-space error,
      // 16 pixels, and no farther: the geometric errors bound what a viewer shows.
      check(atDefault.deepest <= 16, `${name}: at the default target the surface shows background ${atDefault.deepest} pixels inside its outline at ${query}`);
      check(full.stats.settled && tiled.stats.settled && byDefault.stats.settled, `${name}: the renderer did not settle at ${query}`);
    }
    check(result.cracks.some((c) => c.visible_leaf_tiles > 0 && c.visible_tiles > c.visible_leaf_tiles),
          `${name}: no view mixed levels`);
    if (name === 'dragon_vrip') {
      // Where the dragon spans 512 pixels, at the default error target.
      const probe = await view(page, url, 'mask&errorTarget=0&distance=3');
      const d = (3 * probe.span / 512).toFixed(4);
      const full = await view(page, url, `mask&errorTarget=0&distance=${d}`);
      const tiled = await view(page, url, `mask&distance=${d}`);
      const { differ } = compare(full, tiled);
      result.span512 = { distance: Number(d), span: full.span, loaded_triangles: tiled.stats.loadedTriangles,
                         loaded_fraction: tiled.stats.loadedTriangles / triangles, silhouette_differ: differ,
                         silhouette_fraction: differ / full.covered };
      check(result.span512.loaded_fraction <= 0.10, `dragon_vrip at 512 pixels loads ${(100 * result.span512.loaded_fraction).toFixed(1)}% of its triangles`);
      check(result.span512.silhouette_fraction <= 0.01, `dragon_vrip at 512 pixels: silhouette differs in ${(100 * result.span512.silhouette_fraction).toFixed(2)}%`);
    }
    // Shaded pictures for people.
    for (const [label, query] of [['far', 'distance=4'], ['near', `target=${target}&range=${rangeFor(40)}`]]) {
      await page.goto(`${url}?${query}`);
      await page.waitForFunction(() => window.facetreeViewer);
      await page.evaluate(() => window.facetreeViewer.settle());
      await page.screenshot({ path: path.join(dir, `${label}.png`) });
    }
    const errors = await page.evaluate(() => window.facetreeViewer.stats().errors);
    check(errors.length === 0 && pageErrors.length === 0, `${name}: errors in the page: ${[...errors, ...pageErrors].join('; ')}`);
  } finally {
    await page.close();
    server.kill();
  }
  return result;
}

(async () => {
  fs.mkdirSync(out, { recursive: true });
  const assembly = path.join(out, 'assembly.ply');
  run(cli, 'gen', 'assembly', '-n', '300000', '-o', assembly);
  const browser = await chromium.launch({
    executablePath: '/usr/bin/chromium',
    args: ['--headless', '--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--disable-gpu',
           '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
  });
  const results = {};
  try {
    results.dragon_vrip = await testMesh(browser, 'dragon_vrip', path.join(data, 'dragon_vrip.ply.zst'), 871414);
    results.fg_hawaii = await testMesh(browser, 'fg_hawaii', path.join(data, 'fg_hawaii.ply.zst'), 3192083);
    results.assembly = await testMesh(browser, 'assembly', assembly, 295704);
  } catch (e) {
    failures.push(`unexpected: ${e.stack}`);
  } finally {
    await browser.close();
  }
  console.log(JSON.stringify({ results, failures }, null, 1));
  process.exit(failures.length ? 1 : 0);
})();
