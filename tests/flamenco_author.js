// A stand-in for Flamenco Manager's job compiler environment, for the tests: the documented `author` API
// (author.Task(name, type) with addCommand and addDependency, author.Command(name, parameters)) and a job with
// settings and addTask. Usage: node flamenco_author.js JOB_TYPE.js '{"setting": value, ...}'
// Prints {"job_type": JOB_TYPE, "tasks": [{name, type, commands: [{name, parameters}], dependencies: [names]}]}.
const fs = require("fs");
const vm = require("vm");

const [script, given] = process.argv.slice(2);
const author = {
    Task(name, type) {
        return {
            name, type, commands: [], dependencies: [],
            addCommand(command) { this.commands.push(command); },
            addDependency(task) { this.dependencies.push(task.name); },
        };
    },
    Command(name, parameters) { return { name, parameters }; },
};
const context = vm.createContext({ author });
vm.runInContext(fs.readFileSync(script, "utf8"), context, { filename: script });
const jobType = vm.runInContext("JOB_TYPE", context);
const settings = {};
for (const setting of jobType.settings) {
    if ("default" in setting) settings[setting.key] = setting.default;
}
Object.assign(settings, JSON.parse(given));
const tasks = [];
vm.runInContext("compileJob", context)({ settings, addTask(task) { tasks.push(task); } });
const plain = tasks.map(({ name, type, commands, dependencies }) => ({ name, type, commands, dependencies }));
console.log(JSON.stringify({ job_type: jobType, tasks: plain }));
