// The page's link to the video head: the event socket (state pushed as it changes, SETs
// answered) and plain REST for the rest. docs/web.md describes both.

export const socketUrl = (path) => `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${path}`;

export class Api {
  constructor() {
    this.params = null;
    this.status = null;
    this.listeners = { params: [], status: [], connection: [] };
    this.pending = new Map();
    this.nextId = 1;
    this.connect();
  }

  on(kind, listener) {
    this.listeners[kind].push(listener);
  }

  emit(kind, value) {
    for (const listener of this.listeners[kind]) listener(value);
  }

  connect() {
    const socket = new WebSocket(socketUrl('/api/events'));
    socket.onopen = () => this.emit('connection', true);
    socket.onmessage = (event) => {
      const message = JSON.parse(event.data);
      if (message.params) {
        this.params = message.params;
        this.emit('params', this.params);
      } else if (message.status) {
        this.status = message.status;
        this.emit('status', this.status);
      } else if (this.pending.has(message.id)) {
        const { resolve, reject } = this.pending.get(message.id);
        this.pending.delete(message.id);
        if ('ok' in message) resolve(message.ok);
        else reject(new Error(message.error));
      }
    };
    socket.onclose = () => {
      this.socket = null;
      for (const { reject } of this.pending.values()) reject(new Error('the connection closed'));
      this.pending.clear();
      this.emit('connection', false);
      setTimeout(() => this.connect(), 1000);
    };
    this.socket = socket;
  }

  // SETs one parameter type's fields; resolves with its value after the change, rejects with
  // the video head's reason.
  set(param, fields) {
    if (!this.socket || this.socket.readyState !== WebSocket.OPEN) {
      return Promise.reject(new Error('not connected'));
    }
    const id = this.nextId++;
    this.socket.send(JSON.stringify({ id, set: param, fields }));
    return new Promise((resolve, reject) => this.pending.set(id, { resolve, reject }));
  }

  async get(path) {
    const response = await fetch(path);
    if (!response.ok) throw new Error(`${path}: ${response.status}`);
    return response.json();
  }
}
