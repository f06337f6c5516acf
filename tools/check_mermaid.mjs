// Parse `clark explain --format mermaid` output with the real Mermaid parser (offline check).
// Setup once: npm install mermaid@11 jsdom@25 (in any folder), then
//   node tools/check_mermaid.mjs diagram.mmd ...   (exit 1 if any fails to parse)
import { JSDOM } from "jsdom";
import fs from "fs";
const dom = new JSDOM("<!DOCTYPE html><body></body>");
globalThis.window = dom.window; globalThis.document = dom.window.document;
globalThis.DOMPurify = undefined;
const { default: mermaid } = await import("mermaid");
mermaid.initialize({ startOnLoad: false });
let bad = 0;
for (const f of process.argv.slice(2)) {
  const text = fs.readFileSync(f, "utf8");
  try { const r = await mermaid.parse(text); console.log("ok", f, r && r.diagramType); }
  catch (e) { bad++; console.log("FAIL", f, String(e.message || e).slice(0, 300)); }
}
process.exit(bad ? 1 : 0);
