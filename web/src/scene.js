// three.js: a stick character (joint spheres, bone cylinders) on a floor, the camera following the root.
import * as THREE from 'three';

export class Scene {
  constructor(container, parents) {
    this.parents = parents;
    this.renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true, powerPreference: 'low-power' });
    this.renderer.setPixelRatio(1);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.05, 200);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(3, 6, 2);
    this.scene.add(sun);
    this.scene.background = new THREE.Color(0xdfe6ee);
    this.grid = new THREE.Group(); // a 40-m floor with marks, moved along with the character
    const floor = new THREE.Mesh(new THREE.PlaneGeometry(40, 40), new THREE.MeshBasicMaterial({ color: 0xc9d3c0 }));
    floor.rotation.x = -Math.PI / 2;
    const dot = new THREE.CircleGeometry(0.08, 6).rotateX(-Math.PI / 2).translate(0, 0.004, 0);
    const marks = new THREE.InstancedMesh(dot, new THREE.MeshBasicMaterial({ color: 0x6d7d63 }), 13 * 13);
    const m = new THREE.Matrix4(); // a mark every 2 m: the floor shows the character's speed
    for (let i = 0; i < 13; i++) for (let k = 0; k < 13; k++) marks.setMatrixAt(13 * i + k, m.makeTranslation(2 * i - 12, 0, 2 * k - 12));
    this.grid.add(floor, marks);
    this.scene.add(this.grid);
    const body = new THREE.MeshLambertMaterial({ color: 0x1f77b4 });
    const joint = new THREE.SphereGeometry(0.045, 8, 6);
    const bone = new THREE.CylinderGeometry(0.025, 0.025, 1, 6);
    bone.translate(0, 0.5, 0);
    this.joints = parents.map(() => this.scene.add(new THREE.Mesh(joint, body)).children.at(-1));
    this.bones = parents.map((p) => (p < 0 ? null : this.scene.add(new THREE.Mesh(bone, body)).children.at(-1)));
    this.target = new THREE.Vector3(0, 0.9, 0);
    this.up = new THREE.Vector3(0, 1, 0);
    this.resize();
    window.addEventListener('resize', () => this.resize());
  }

  resize() {
    const w = window.innerWidth, h = window.innerHeight;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  // world: Float64Array(63) joint positions (x, y, z) in metres; smooth: 0..1 how far the camera catches up
  draw(world, smooth = 0.15) {
    const v = (j) => new THREE.Vector3(world[3 * j], world[3 * j + 1], world[3 * j + 2]);
    this.parents.forEach((p, j) => {
      const a = v(j);
      this.joints[j].position.copy(a);
      if (p >= 0) {
        const b = v(p), dir = a.clone().sub(b), len = dir.length();
        const m = this.bones[j];
        m.position.copy(b);
        m.scale.set(1, Math.max(len, 1e-6), 1);
        m.quaternion.setFromUnitVectors(this.up, dir.normalize());
      }
    });
    const hips = new THREE.Vector3(world[0], 0.9, world[2]);
    this.target.lerp(hips, smooth);
    this.camera.position.set(this.target.x + 2.8, 2.0, this.target.z + 3.6);
    this.camera.lookAt(this.target);
    this.grid.position.set(2 * Math.round(this.target.x / 2), 0, 2 * Math.round(this.target.z / 2));
    this.renderer.render(this.scene, this.camera);
  }

  sync() { // wait until the GPU has drawn the frame (so a measured frame time includes the render)
    const gl = this.renderer.getContext(), px = new Uint8Array(4);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
  }
}
