#!/usr/bin/env python3
"""Serves a tileset and the viewer page on 127.0.0.1 and prints the page's address.
  serve.py TILESET_DIR NODE_MODULES [--port P]   (P 0, the default: any free port)
/ is the page, /tileset/ the tileset's folder, /node_modules/ the npm packages it loads."""
import http.server
import os
import sys
from functools import partial

HERE = os.path.dirname(os.path.abspath(__file__))


class Handler(http.server.SimpleHTTPRequestHandler):
    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map,
                      '.js': 'text/javascript', '.mjs': 'text/javascript', '.wasm': 'application/wasm',
                      '.glb': 'model/gltf-binary', '.json': 'application/json'}

    def __init__(self, *args, tileset, node_modules, **kwargs):
        self.roots = {'/tileset/': tileset, '/node_modules/': node_modules}
        super().__init__(*args, directory=HERE, **kwargs)

    def translate_path(self, path):
        clean = path.split('?', 1)[0].split('#', 1)[0]
        for prefix, root in self.roots.items():
            if clean.startswith(prefix):
                relative = os.path.normpath(clean[len(prefix):]).lstrip('/')
                if relative.startswith('..'):
                    return os.path.join(root, '.missing')
                return os.path.join(root, relative)
        if clean in ('/', '/index.html'):
            return os.path.join(HERE, 'index.html')
        if clean == '/viewer.js':
            return os.path.join(HERE, 'viewer.js')
        return os.path.join(HERE, '.missing')

    def do_GET(self):
        if self.path == '/favicon.ico':
            self.send_response(204)
            self.end_headers()
            return
        super().do_GET()

    def end_headers(self):
        self.send_header('Cache-Control', 'no-store')
        super().end_headers()

    def log_message(self, *args):
        pass


def main():
    args = sys.argv[1:]
    port = 0
    if '--port' in args:
        i = args.index('--port')
        port = int(args[i + 1])
        del args[i:i + 2]
    if len(args) != 2:
        sys.exit(__doc__)
    tileset, node_modules = (os.path.abspath(a) for a in args)
    if not os.path.isfile(os.path.join(tileset, 'tileset.json')):
        sys.exit(f'view: {tileset}: no tileset.json (write one with facetree tiles FILE.fch -o DIR)')
    server = http.server.ThreadingHTTPServer(
        ('127.0.0.1', port), partial(Handler, tileset=tileset, node_modules=node_modules))
    print(f'http://127.0.0.1:{server.server_address[1]}/', flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass


if __name__ == '__main__':
    main()
