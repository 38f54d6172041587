// The dashboard is served by the coordinator from any directory: relative asset paths, and
// everything bundled (no CDN; the page works offline). `npm run dev` proxies the API to a
// coordinator started with --http 127.0.0.1:8080.
import { defineConfig } from "vitest/config";

export default defineConfig({
  base: "./",
  build: { outDir: "dist", emptyOutDir: true, assetsInlineLimit: 0, chunkSizeWarningLimit: 600 },
  server: { proxy: { "/api": "http://127.0.0.1:8080", "/healthz": "http://127.0.0.1:8080" } },
  test: { environment: "node", include: ["src/**/*.test.ts"] },
});
