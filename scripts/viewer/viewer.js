// The tileset at /tileset/tileset.json in three.js with 3DTilesRendererJS, as a viewer streams it:
// the renderer picks the tiles whose geometric error exceeds errorTarget pixels on screen.
// Options in the address:
//   ?errorTarget=E   pixels (0 loads the leaves everywhere: the full resolution)
//   ?mask            unlit black surface on white, no antialiasing, drawn only when asked
//   ?tileColours     each tile unlit in a colour of its own
//   ?span=S          the model's bounding sphere S pixels across
//   ?distance=D      the camera D bounding-sphere radii from the centre (instead of span)
//   ?target=X,Y,Z    the centre looked at, in the tileset's coordinates (default the sphere's)
//   ?range=R         the camera R model units from the centre
//   ?azimuth=A&elevation=E   degrees, the camera seen from the centre
// window.facetreeViewer is what the browser tests read: settle(), stats(), maskBase64().
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { TilesRenderer } from '3d-tiles-renderer';
import { GLTFExtensionsPlugin } from '3d-tiles-renderer/plugins';

const params = new URLSearchParams(location.search);
const mask = params.has('mask');
const renderer = new THREE.WebGLRenderer({ antialias: !mask, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(innerWidth, innerHeight);
renderer.setClearColor(0xffffff);
document.body.appendChild(renderer.domElement);

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(45, innerWidth / innerHeight, 1e-3, 1e3);
scene.add(new THREE.HemisphereLight(0xffffff, 0x555555, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(1, 2, 3);
scene.add(sun);

const tiles = new TilesRenderer('/tileset/tileset.json');
tiles.registerPlugin(new GLTFExtensionsPlugin({
  dracoLoader: new DRACOLoader().setDecoderPath('/node_modules/three/examples/jsm/libs/draco/gltf/'),
}));
if (params.has('errorTarget')) tiles.errorTarget = Number(params.get('errorTarget'));
tiles.group.rotation.x = -Math.PI / 2;  // 3D Tiles' z up as three.js's y up
scene.add(tiles.group);
tiles.setCamera(camera);
tiles.setResolutionFromRenderer(camera, renderer);

const errors = [];
const black = new THREE.MeshBasicMaterial({ color: 0x000000, side: THREE.DoubleSide });
tiles.addEventListener('load-error', (e) => errors.push(String(e.error?.message ?? e.error ?? e.url)));
let loadedModels = 0;
tiles.addEventListener('load-model', ({ scene: model }) => {
  const colour = new THREE.Color().setHSL((loadedModels++ * 0.618) % 1, 0.6, 0.5);
  model.traverse((o) => {
    if (!o.isMesh) return;
    if (mask) o.material = black;
    else if (params.has('tileColours')) o.material = new THREE.MeshBasicMaterial({ color: colour, side: THREE.DoubleSide });
  });
});

const controls = new OrbitControls(camera, renderer.domElement);
let framed = false;

// Places the camera once the root is known: the bounding sphere `span` pixels across, or at
// `distance` radii, looking at its centre from the azimuth and elevation given.
function frame() {
  const sphere = new THREE.Sphere();
  if (!tiles.getBoundingSphere(sphere)) return false;
  tiles.group.updateMatrixWorld(true);
  sphere.applyMatrix4(tiles.group.matrixWorld);  // the tileset's frame turned to y up
  const centre = sphere.center.clone();
  if (params.has('target')) centre.fromArray(params.get('target').split(',').map(Number)).applyMatrix4(tiles.group.matrixWorld);
  const fov = THREE.MathUtils.degToRad(camera.fov);
  const span = Number(params.get('span') ?? Math.min(innerWidth, innerHeight) * 0.8);
  const distance = params.has('range') ? Number(params.get('range'))
                 : params.has('distance') ? Number(params.get('distance')) * sphere.radius
                 : sphere.radius * innerHeight / (span * Math.tan(fov / 2));
  const azimuth = THREE.MathUtils.degToRad(Number(params.get('azimuth') ?? 30));
  const elevation = THREE.MathUtils.degToRad(Number(params.get('elevation') ?? 20));
  const direction = new THREE.Vector3(Math.cos(elevation) * Math.sin(azimuth), Math.sin(elevation),
                                      Math.cos(elevation) * Math.cos(azimuth));
  camera.position.copy(centre).addScaledVector(direction, distance);
  const reach = camera.position.distanceTo(sphere.center);
  camera.near = Math.max(reach - sphere.radius, distance * 1e-2) * 0.5;
  camera.far = (reach + sphere.radius) * 2;
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.update();
  return true;
}

function draw() {
  if (!framed) framed = frame();
  camera.updateMatrixWorld();
  tiles.update();
  renderer.render(scene, camera);
}

function triangles(object) {
  let n = 0;
  object.traverse((o) => {
    if (o.isMesh) n += (o.geometry.index ? o.geometry.index.count : o.geometry.attributes.position.count) / 3;
  });
  return n;
}

function stats() {
  let loaded = 0, loadedTiles = 0, visible = 0, leaves = 0;
  tiles.forEachLoadedModel((model) => { loaded += triangles(model); loadedTiles++; });
  for (const tile of tiles.visibleTiles) {
    visible += tile.engineData?.scene ? triangles(tile.engineData.scene) : 0;
    if (!tile.children || tile.children.length === 0) leaves++;
  }
  return { framed, errors, loadedTriangles: loaded, loadedTiles, visibleTriangles: visible,
           visibleTiles: tiles.visibleTiles.size, visibleLeafTiles: leaves, ...tiles.stats };
}

// Resolves once nothing is queued, downloading or parsing for several frames in a row; the
// frames update the tiles without drawing them (software rendering takes the time), then it draws.
function settle(maxFrames = 3000) {
  return new Promise((resolve) => {
    let quiet = 0, frames = 0;
    const step = () => {
      if (!framed) framed = frame();
      camera.updateMatrixWorld();
      tiles.update();
      const s = tiles.stats;
      quiet = framed && s.queued + s.downloading + s.parsing === 0 && tiles.rootTileset ? quiet + 1 : 0;
      if (quiet >= 8 || ++frames >= maxFrames) {
        draw();
        resolve({ settled: quiet >= 8, frames, ...stats() });
      } else {
        setTimeout(step, 5);
      }
    };
    step();
  });
}

// The picture as one byte a pixel, 1 where the surface covers it (not the white background), rows
// from the top, in base64.
function maskBase64() {
  draw();
  const gl = renderer.getContext();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const rgba = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
  const bits = new Uint8Array(w * h);
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++) {
      const i = ((h - 1 - y) * w + x) * 4;
      bits[y * w + x] = rgba[i] < 128 || rgba[i + 1] < 128 || rgba[i + 2] < 128 ? 1 : 0;
    }
  let text = '';
  for (let i = 0; i < bits.length; i += 8192) text += String.fromCharCode(...bits.subarray(i, i + 8192));
  return { width: w, height: h, bits: btoa(text) };
}

window.facetreeViewer = { settle, stats, maskBase64 };
const info = document.getElementById('info');
// A person's view redraws continuously; the tests' masks draw when asked.
if (!mask) renderer.setAnimationLoop(() => {
  draw();
  const s = stats();
  info.textContent = `${s.visibleTiles} tiles shown (${s.visibleLeafTiles} at full resolution), ` +
                     `${s.visibleTriangles.toLocaleString()} triangles; ${s.loadedTiles} loaded` +
                     (errors.length ? `; errors: ${errors.join('; ')}` : '');
});
window.addEventListener('resize', () => {
  camera.aspect = innerWidth / innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(innerWidth, innerHeight);
  tiles.setResolutionFromRenderer(camera, renderer);
});
