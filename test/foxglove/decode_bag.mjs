// Decode every message of MCAP bag files with the libraries Foxglove uses to open ROS 2 bags
// (@mcap/core + @mcap/support for the container and its chunk compression, @foxglove/rosmsg
// for the 'ros2msg' schema text, @foxglove/rosmsg2-serialization for the CDR messages).
//
// Usage: node decode_bag.mjs FILE.mcap [MORE.mcap ...]
// Prints one JSON object: {topic: {type, count, failures, errors, messages}} where errors holds
// the first distinct decoding errors and messages one row per decoded message, in file order:
// [log time ns, header stamp ns or null, first float field or null, sum of the float fields,
// number of float values] (integers as decimal strings, NaN as null). Exit 0 when the files
// were read (decoding failures are in the output), 1 when a file cannot be read.

import { readFile } from 'node:fs/promises';

import { parse } from '@foxglove/rosmsg';
import { MessageReader } from '@foxglove/rosmsg2-serialization';
import { McapStreamReader } from '@mcap/core';
import { loadDecompressHandlers } from '@mcap/support';

const FLOAT_TYPES = new Set(['float32', 'float64']);
const MAX_ERRORS = 3;

function floatValues(value, definition, definitions, out) {
  for (const field of definition.definitions) {
    if (field.isConstant) {
      continue;
    }
    const fieldValue = value[field.name];
    const items = field.isArray ? Array.from(fieldValue) : [fieldValue];
    if (field.isComplex) {
      const nested = definitions.get(field.type);
      if (nested === undefined) {
        throw new Error(`no definition of ${field.type}`);
      }
      for (const item of items) {
        floatValues(item, nested, definitions, out);
      }
    } else if (FLOAT_TYPES.has(field.type)) {
      out.push(...items);
    }
  }
  return out;
}

function headerStamp(message) {
  const stamp = message?.header?.stamp;
  if (stamp === undefined) {
    return null;
  }
  return (BigInt(stamp.sec) * 1000000000n + BigInt(stamp.nanosec)).toString();
}

function finite(value) {
  return Number.isFinite(value) ? value : null;
}

class Channel {
  constructor(topic, schema) {
    this.summary = { type: schema.name, count: 0, failures: 0, errors: [], messages: [] };
    try {
      const parsed = parse(new TextDecoder().decode(schema.data), { ros2: true });
      this.root = parsed[0];
      this.definitions = new Map(parsed.slice(1).map((definition) => [definition.name, definition]));
      this.reader = new MessageReader(parsed);
    } catch (error) {
      this.schemaError = `schema ${schema.name}: ${error.message}`;
    }
  }

  decode(record) {
    const summary = this.summary;
    summary.count += 1;
    try {
      if (this.schemaError !== undefined) {
        throw new Error(this.schemaError);
      }
      const message = this.reader.readMessage(record.data);
      const floats = floatValues(message, this.root, this.definitions, []);
      const sum = floats.reduce((total, value) => total + value, 0);
      summary.messages.push([record.logTime.toString(), headerStamp(message),
        floats.length ? finite(floats[0]) : null, finite(sum), floats.length]);
    } catch (error) {
      summary.failures += 1;
      if (summary.errors.length < MAX_ERRORS && !summary.errors.includes(error.message)) {
        summary.errors.push(error.message);
      }
    }
  }
}

async function decodeFiles(paths) {
  const decompressHandlers = await loadDecompressHandlers();
  const topics = {};
  for (const path of paths) {
    const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
    reader.append(await readFile(path));
    const schemas = new Map();
    const channels = new Map();
    for (let record; (record = reader.nextRecord()) !== undefined;) {
      if (record.type === 'Schema') {
        schemas.set(record.id, record);
      } else if (record.type === 'Channel') {
        if (!(record.topic in topics)) {
          topics[record.topic] = new Channel(record.topic, schemas.get(record.schemaId));
        }
        channels.set(record.id, topics[record.topic]);
      } else if (record.type === 'Message') {
        channels.get(record.channelId).decode(record);
      }
    }
    if (!reader.done()) {
      throw new Error(`${path}: the file ends before the MCAP footer`);
    }
  }
  return Object.fromEntries(Object.entries(topics).map(([topic, c]) => [topic, c.summary]));
}

try {
  process.stdout.write(JSON.stringify(await decodeFiles(process.argv.slice(2))) + '\n');
} catch (error) {
  process.stderr.write(`decode_bag: ${error.message}\n`);
  process.exit(1);
}
