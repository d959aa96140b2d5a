// The microphone's samples, passed to the page as they come (push-to-talk in face.js).
class Recorder extends AudioWorkletProcessor {
  process(inputs) {
    const samples = inputs[0] && inputs[0][0];
    if (samples) this.port.postMessage(samples.slice(0));
    return true;
  }
}
registerProcessor("recorder", Recorder);
