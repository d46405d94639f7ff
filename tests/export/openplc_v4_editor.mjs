// Runs the OpenPLC v4 editor's own TypeScript (a checkout of Autonomy-Logic/openplc-editor,
// never copied into this repository) on an exported project folder, outside Electron.
//
//   node openplc_v4_editor.mjs EDITOR_CHECKOUT load PROJECT_DIR   -> JSON on stdout
//   node openplc_v4_editor.mjs EDITOR_CHECKOUT xml PROJECT_DIR    -> PLCopen XML on stdout
//   node openplc_v4_editor.mjs EDITOR_CHECKOUT modbus PROJECT_DIR -> conf/modbus_slave.json
//
// `load`: the project.json checked against the editor's zod schema (PLCProjectSchema), then
// the folder opened by the editor's loader (readProjectFiles, on a copy: it writes default
// device files into the folder it opens). `xml`: the loaded project turned into the PLCopen
// XML that the editor's build hands to xml2st (its XmlGenerator for the "old-editor"
// dialect, called part by part because 4.1's XmlGenerator also insists on a program named
// "main", a check later editors dropped). `modbus`: what the editor's build for OpenPLC Runtime
// v4 writes into the upload as conf/modbus_slave.json from the loaded project's servers
// (generateModbusSlaveConfig; "null" when the project has no Modbus TCP server).
//
// esbuild bundles just those modules, found from the checkout upward (install it, zod and
// xmlbuilder2 beside the checkout: docs/exports.md). Every other package they pull in
// through the editor's index modules (electron, react-i18next, lodash, yaml, ...) and the
// editor's i18n set-up are replaced by stubs: the code run here calls none of them (i18n
// only on its error paths, where a stub returns the message key).
import { builtinModules, createRequire } from 'node:module'
import { cpSync, mkdtempSync, rmSync } from 'node:fs'
import { tmpdir } from 'node:os'
import { join } from 'node:path'

const [, , checkout, command, projectDir] = process.argv
const require = createRequire(join(checkout, 'package.json'))
let esbuild
try {
  esbuild = require('esbuild')
} catch {
  console.error(`no esbuild found from ${checkout} upward: npm install esbuild zod@3 ` +
    'xmlbuilder2@3 into the folder above the checkout (docs/exports.md)')
  process.exit(3)
}

const entry = `
import { PLCProjectSchema } from '@root/types/PLC/open-plc'
import { readProjectFiles } from '@root/main/services/project-service/utils/read-project'
import {
  getBaseOldEditorXmlStructure, oldEditorInstanceToXml, oldEditorParseDataTypesToXML,
  oldEditorParsePousToXML,
} from '@root/utils/PLC/xml-generator/old-editor'
import { generateModbusSlaveConfig } from '@root/utils/modbus/generate-modbus-slave-config'
import { create } from 'xmlbuilder2'
export { PLCProjectSchema, readProjectFiles, generateModbusSlaveConfig }
export function projectXml(data) {
  let xml = getBaseOldEditorXmlStructure()
  xml = oldEditorParsePousToXML(xml, data.pous)
  xml = oldEditorParseDataTypesToXML(xml, data.dataTypes)
  xml = oldEditorInstanceToXml(xml, data.configuration)
  const doc = create(xml)
  doc.dec({ version: '1.0', encoding: 'utf-8' })
  return doc.end({ prettyPrint: true })
}
`

const BUNDLED = new Set(['zod', 'xmlbuilder2'])
const stubs = {
  name: 'stubs',
  setup(build) {
    build.onResolve({ filter: /(^|\/)i18n$/ }, (args) =>
      args.importer.startsWith(join(checkout, 'src')) ? { path: 'i18n', namespace: 'stub' } : undefined)
    build.onResolve({ filter: /^[^./]/ }, (args) => {
      const pkg = args.path.startsWith('@') ? args.path.split('/').slice(0, 2).join('/')
        : args.path.split('/')[0]
      const fromEditor = args.importer === '<stdin>' || args.importer.startsWith(join(checkout, 'src'))
      if (!fromEditor || args.path.startsWith('@root/') || BUNDLED.has(pkg) || builtinModules.includes(pkg) ||
          pkg.startsWith('node:')) return undefined
      return { path: pkg, namespace: 'stub' }
    })
    build.onLoad({ filter: /^i18n$/, namespace: 'stub' }, () => ({
      contents: 'export const i18n = { t: (key) => key }; export default i18n', loader: 'js',
    }))
    build.onLoad({ filter: /.*/, namespace: 'stub' }, () => ({
      // any named import is a function that does nothing
      contents: 'const f = () => f; module.exports = new Proxy(f, { get: (_, k) => ' +
        "k === '__esModule' ? false : f })",
      loader: 'js',
    }))
  },
}

const work = mkdtempSync(join(tmpdir(), 'openplc-v4-'))
try {
  const bundle = join(work, 'editor.cjs')
  await esbuild.build({
    stdin: { contents: entry, resolveDir: join(checkout, 'src'), loader: 'ts' },
    bundle: true, platform: 'node', format: 'cjs', outfile: bundle, logLevel: 'error',
    alias: { '@root': join(checkout, 'src') }, plugins: [stubs],
  })
  const editor = require(bundle)
  const copy = join(work, 'project')
  cpSync(projectDir, copy, { recursive: true })
  const raw = JSON.parse((await import('node:fs')).readFileSync(join(copy, 'project.json'), 'utf-8'))
  const schema = editor.PLCProjectSchema.safeParse(raw)
  const log = console.log
  console.log = () => {} // the loader reports migrations on stdout
  const loaded = await editor.readProjectFiles(copy)
  console.log = log
  if (command === 'load') {
    process.stdout.write(JSON.stringify({
      schema: schema.success ? { success: true } : { success: false, issues: schema.error.issues },
      loaded,
    }))
  } else if (command === 'xml') {
    if (!loaded.success) throw new Error(`the editor did not open ${projectDir}`)
    const { project, pous } = loaded.data
    process.stdout.write(editor.projectXml({ ...project.data, pous }))
  } else if (command === 'modbus') {
    if (!loaded.success) throw new Error(`the editor did not open ${projectDir}`)
    // the build reads the servers of the project the editor holds: project.json's data
    process.stdout.write(String(editor.generateModbusSlaveConfig(loaded.data.project.data.servers)))
  } else {
    throw new Error(`unknown command ${command}`)
  }
} finally {
  rmSync(work, { recursive: true, force: true })
}
