#!/usr/bin/env node
// A real G-code sender against a grbl board: starts cncjs's server
// headless, connects to it as its web page would (a signed token, its
// socket.io client), opens the board's serial port as a Grbl controller,
// loads and starts a G-code file, and prints one JSON object when the
// program has finished and the machine is idle: the last `Grbl:state`'s
// machine position, the sender's counts, the board's error and alarm lines.
//
//   node run.js --port /dev/pts/N --gcode FILE [--at MS:COMMAND[:ARG]]... [--timeout-ms N]
//
// `--at 800:feedhold` emits cncjs's `command` COMMAND (feedhold,
// cyclestart, feedOverride:10, reset, unlock, ...) MS milliseconds after
// the program started. Exit code 0 when the program finished, 1 otherwise.
'use strict';

const fs = require('fs');
const os = require('os');
const path = require('path');
const net = require('net');
const crypto = require('crypto');
const { spawn } = require('child_process');

const jwt = require('jsonwebtoken');
const io = require('socket.io-client');

function parseArgs(argv) {
  const args = { at: [], timeoutMs: 120000 };
  for (let i = 2; i < argv.length; i += 1) {
    const flag = argv[i];
    const value = argv[i + 1];
    i += 1;
    if (flag === '--port') args.port = value;
    else if (flag === '--gcode') args.gcode = value;
    else if (flag === '--timeout-ms') args.timeoutMs = Number(value);
    else if (flag === '--at') {
      const [ms, command, arg] = value.split(':');
      args.at.push({ ms: Number(ms), command, arg: arg === undefined ? undefined : Number(arg) });
    } else {
      throw new Error(`unknown option ${flag}`);
    }
  }
  if (!args.port || !args.gcode) {
    throw new Error('usage: run.js --port PTY --gcode FILE [--at MS:COMMAND[:ARG]]...');
  }
  return args;
}

function freeTcpPort() {
  return new Promise((resolve, reject) => {
    const server = net.createServer();
    server.on('error', reject);
    server.listen(0, '127.0.0.1', () => {
      const { port } = server.address();
      server.close(() => resolve(port));
    });
  });
}

function sleep(ms) {
  return new Promise((resolve) => setTimeout(resolve, ms));
}

async function main() {
  const args = parseArgs(process.argv);
  const gcode = fs.readFileSync(args.gcode, 'utf8');
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'cogstep-cncjs-'));
  const secret = crypto.randomBytes(16).toString('hex');
  const config = path.join(dir, 'cncrc.json');
  fs.writeFileSync(config, JSON.stringify({ secret, state: { checkForUpdates: false } }));
  const httpPort = await freeTcpPort();
  const cncjs = path.join(__dirname, 'node_modules', 'cncjs', 'bin', 'cncjs');
  const server = spawn(process.execPath, [cncjs, '-H', '127.0.0.1', '-p', String(httpPort), '-c', config], {
    stdio: ['ignore', 'ignore', 'pipe'],
    env: { ...process.env, HOME: dir },
  });
  let serverLog = '';
  server.stderr.on('data', (chunk) => { serverLog += chunk; });

  const result = {
    finished: false,
    mpos: null,
    activeState: null,
    sent: 0,
    received: 0,
    total: 0,
    errors: [],
    alarms: [],
    elapsed_ms: 0,
    hold_seen: false,
  };
  let socket = null;
  const done = (code) => {
    if (socket) socket.close();
    server.kill('SIGTERM');
    fs.rmSync(dir, { recursive: true, force: true });
    process.stdout.write(`${JSON.stringify(result)}\n`);
    process.exit(code);
  };
  setTimeout(() => {
    result.timeout = true;
    result.server_log = serverLog.slice(-2000);
    done(1);
  }, args.timeoutMs);

  // The token cncjs's own page would hold (no users configured: any id).
  const token = jwt.sign({ id: '', name: '' }, secret, { expiresIn: '1h' });
  for (let attempt = 0; ; attempt += 1) {
    const connected = await new Promise((resolve) => {
      const s = io.connect(`http://127.0.0.1:${httpPort}`, { query: `token=${token}`, reconnection: false });
      s.on('connect', () => resolve(s));
      s.on('connect_error', () => { s.close(); resolve(null); });
      s.on('error', () => { s.close(); resolve(null); });
    });
    if (connected) { socket = connected; break; }
    if (attempt > 200) throw new Error('cncjs server did not come up');
    await sleep(100);
  }

  let startedAt = 0;
  let finishTime = 0;
  let ready = false;
  let loaded = false;
  const start = () => {
    if (loaded) return;
    loaded = true;
    socket.emit('command', args.port, 'gcode:load', path.basename(args.gcode), gcode, {}, (err) => {
      if (err) { result.load_error = String(err); done(1); return; }
      startedAt = Date.now();
      socket.emit('command', args.port, 'gcode:start');
      for (const action of args.at) {
        setTimeout(() => {
          const extra = action.arg === undefined ? [] : [action.arg];
          socket.emit('command', args.port, action.command, ...extra);
        }, action.ms);
      }
    });
  };

  socket.on('serialport:read', (line) => {
    const text = String(line).trim();
    if (text.startsWith('error:')) result.errors.push(text);
    if (text.startsWith('ALARM:')) result.alarms.push(text);
    if (text.startsWith('Grbl ') && !ready) {
      ready = true;
      // cncjs sends `$$` on the welcome line; give it its answer first.
      setTimeout(start, 300);
    }
  });
  socket.on('Grbl:state', (state) => {
    const status = state && state.status;
    if (!status) return;
    result.mpos = status.mpos;
    result.activeState = status.activeState;
    if (String(status.activeState).startsWith('Hold')) result.hold_seen = true;
    if (finishTime > 0 && status.activeState === 'Idle' && !result.finished) {
      result.finished = true;
      result.elapsed_ms = finishTime - startedAt;
      // One more report, so that the position is the one at rest.
      setTimeout(() => done(0), 300);
    }
  });
  socket.on('sender:status', (status) => {
    result.sent = status.sent;
    result.received = status.received;
    result.total = status.total;
    if (status.finishTime > 0 && startedAt > 0) finishTime = status.finishTime;
  });

  socket.emit('open', args.port, { controllerType: 'Grbl', baudrate: 115200 }, (err) => {
    if (err) { result.open_error = String(err); done(1); return; }
    // The board's welcome line was written before cncjs opened the port;
    // a soft reset at rest brings a fresh one (and no alarm).
    setTimeout(() => { if (!ready) socket.emit('command', args.port, 'reset'); }, 500);
  });
}

main().catch((error) => {
  process.stdout.write(`${JSON.stringify({ finished: false, error: String(error && error.stack || error) })}\n`);
  process.exit(1);
});
