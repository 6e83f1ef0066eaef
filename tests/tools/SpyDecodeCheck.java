// Decodes every event of the LCM logs given the way lcm-spy does: the class found by the message's
// fingerprint in lcm-spy's own type database (lcm.spy.LCMTypeDatabase, which scans the
// classpath), its (DataInput) constructor. Prints "CHANNEL TYPE COUNT" per channel, and
// "UNDECODED CHANNEL COUNT" for what it could not decode.
import java.io.ByteArrayInputStream;
import java.io.DataInputStream;
import java.io.EOFException;
import java.util.TreeMap;

public class SpyDecodeCheck {
  public static void main(String[] args) throws Exception {
    lcm.spy.LCMTypeDatabase db = new lcm.spy.LCMTypeDatabase();
    TreeMap<String, Integer> ok = new TreeMap<>();
    TreeMap<String, String> types = new TreeMap<>();
    TreeMap<String, Integer> bad = new TreeMap<>();
    for (String path : args) {
    lcm.logging.Log log = new lcm.logging.Log(path, "r");
    while (true) {
      lcm.logging.Log.Event e;
      try {
        e = log.readNext();
      } catch (EOFException end) {
        break;
      }
      if (e.channel.equals("LCM_SELF_TEST")) continue;
      try {
        DataInputStream in = new DataInputStream(new ByteArrayInputStream(e.data));
        long fingerprint = in.readLong();
        Class<?> cls = db.getClassByFingerprint(fingerprint);
        if (cls == null) throw new Exception("no type");
        in = new DataInputStream(new ByteArrayInputStream(e.data));
        cls.getConstructor(java.io.DataInput.class).newInstance(in);
        ok.merge(e.channel, 1, Integer::sum);
        types.put(e.channel, cls.getName());
      } catch (Exception ex) {
        bad.merge(e.channel, 1, Integer::sum);
      }
    }
    }
    for (String ch : ok.keySet()) System.out.println(ch + " " + types.get(ch) + " " + ok.get(ch));
    for (String ch : bad.keySet()) System.out.println("UNDECODED " + ch + " " + bad.get(ch));
  }
}
