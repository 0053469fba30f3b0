// Assemble raspv_hmd/client/levels_kernels.wat into levels_kernels.wasm (the page's drawing kernels).
//   npm install --prefix tools/client wabt@1.0.36 && node tools/client/build_kernels.mjs
// The .wasm carries the sha256 of its .wat in a custom section "raspv-source-sha256";
// tests/hmd/test_levels_kernels.py checks that the committed .wasm was built from the committed .wat.
import { createHash } from "node:crypto";
import { readFileSync, writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const require = createRequire(join(here, "package.json"));
const wabt = await require("wabt")();
const client = join(here, "..", "..", "raspv_hmd", "client");
const source = readFileSync(join(client, "levels_kernels.wat"));
const module = wabt.parseWat("levels_kernels.wat", source.toString(), { simd: true, bulk_memory: true, sat_float_to_int: true });
module.validate();
const { buffer } = module.toBinary({ write_debug_names: false });
// custom section: id 0, size, name (length-prefixed), payload
const name = Buffer.from("raspv-source-sha256"), digest = Buffer.from(createHash("sha256").update(source).digest("hex"));
const body = Buffer.concat([Buffer.from([name.length]), name, digest]);
const section = Buffer.concat([Buffer.from([0, body.length]), body]);
writeFileSync(join(client, "levels_kernels.wasm"), Buffer.concat([Buffer.from(buffer), section]));
console.log(`levels_kernels.wasm: ${buffer.length + section.length} bytes (source sha256 ${digest.toString().slice(0, 12)}…)`);
